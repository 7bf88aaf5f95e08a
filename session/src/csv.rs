//! CSV export of one JSON channel: one row per message, one column per leaf
//! field (`thumb.x`, `corners_px.0.1`), `log_time_ns` first.
//!
//! The columns are the union of every message's fields, in the order the
//! fields appear in the messages (the struct order, not alphabetical). Two
//! passes over the file find them, so a channel whose first message has
//! `null` where later ones have arrays (a missed ArUco detection) still gets
//! every column. Memory stays bounded: rows are streamed.

use std::collections::HashMap;
use std::fmt;
use std::io::{BufWriter, Read, Seek, Write};
use std::path::Path;

use serde::de::{self, DeserializeSeed, MapAccess, SeqAccess, Visitor};

use super::error::SessionError;
use super::reader::{MessageReader, ReadOptions, no_such_topic};
use super::scan::open_session;
use super::stored::{ChannelDesc, RawMessage};

/// Schemas whose channels are refused: their payload is an image, not a table.
const IMAGE_SCHEMAS: [&str; 3] =
    ["foxglove.CompressedImage", "foxglove.RawImage", "foxglove.CompressedVideo"];

/// What [`export_csv`] wrote.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct CsvSummary {
    /// Data rows written (one per message).
    pub rows: u64,
    /// The header, `log_time_ns` first.
    pub columns: Vec<String>,
}

/// Writes the messages of `topic` in `path` as CSV to `out`.
///
/// Fails with [`SessionError::NotTabular`] for image channels and channels not
/// encoded as JSON, [`SessionError::NoSuchTopic`] when the file has no such channel.
pub fn export_csv<W: Write>(
    path: impl AsRef<Path>,
    topic: &str,
    options: ReadOptions,
    out: W,
) -> Result<CsvSummary, SessionError> {
    let path = path.as_ref();
    let (mut file, _) = open_session(path)?;
    export_csv_from_reader(path, &mut file, topic, options, out)
}

/// [`export_csv`] of the session held by `input` (from its start, for example
/// a `Cursor` over the bytes of a file); `name` stands for the file in errors.
pub fn export_csv_from_reader<R: Read + Seek, W: Write>(
    name: impl AsRef<Path>,
    mut input: R,
    topic: &str,
    options: ReadOptions,
    out: W,
) -> Result<CsvSummary, SessionError> {
    let path = name.as_ref();
    let columns = columns(path, &mut input, topic, options)?;

    // Pass 2: the rows.
    let output = |source| SessionError::Output { path: path.to_path_buf(), source };
    let mut out = BufWriter::new(out);
    let mut header = vec!["log_time_ns".to_string()];
    header.extend(columns.iter().cloned());
    write_row(&mut out, header.iter().map(|h| Some(Cell::Str(h.clone())))).map_err(output)?;
    let index: HashMap<&str, usize> = columns.iter().enumerate().map(|(i, c)| (c.as_str(), i)).collect();
    let mut rows = 0;
    let mut fields = Vec::new();
    let mut row: Vec<Option<Cell>> = Vec::new();
    for message in MessageReader::from_reader(path, &mut input, &[topic], options)? {
        let m = message?;
        flatten(path, &m, &mut fields)?;
        row.clear();
        row.resize(columns.len() + 1, None);
        row[0] = Some(Cell::Text(m.log_time.0.to_string()));
        for (key, cell) in fields.drain(..) {
            if let Some(&i) = index.get(key.as_str()) {
                row[i + 1] = Some(cell);
            }
        }
        write_row(&mut out, row.drain(..)).map_err(output)?;
        rows += 1;
    }
    out.flush().map_err(output)?;
    Ok(CsvSummary { rows, columns: header })
}

/// Pass 1: the leaf columns of every message of `topic`, in message order.
fn columns<R: Read + Seek>(
    path: &Path,
    input: &mut R,
    topic: &str,
    options: ReadOptions,
) -> Result<Vec<String>, SessionError> {
    let mut fields = Vec::new();
    let mut columns: Vec<String> = Vec::new();
    let mut reader = MessageReader::from_reader(path, input, &[topic], options)?;
    for message in reader.by_ref() {
        let m = message?;
        check_tabular(path, &m.channel)?;
        flatten(path, &m, &mut fields)?;
        merge_columns(&mut columns, fields.iter().map(|(k, _)| k.as_str()));
    }
    let Some(channel) = reader.channels().find(|c| c.topic == topic) else {
        return Err(no_such_topic(path.to_path_buf(), topic, reader.channels()));
    };
    check_tabular(path, channel)?;
    // A field that is null in some messages and an object or array in
    // others keeps only the leaf columns.
    let parents: Vec<String> = columns
        .iter()
        .filter(|c| {
            columns
                .iter()
                .any(|d| d.len() > c.len() && d.starts_with(c.as_str()) && d.as_bytes()[c.len()] == b'.')
        })
        .cloned()
        .collect();
    columns.retain(|c| !parents.contains(c));
    Ok(columns)
}

fn check_tabular(path: &Path, c: &ChannelDesc) -> Result<(), SessionError> {
    if IMAGE_SCHEMAS.contains(&c.schema_name.as_str()) || c.message_encoding != "json" {
        return Err(SessionError::NotTabular {
            path: path.to_path_buf(),
            topic: c.topic.clone(),
            reason: format!("schema {} in encoding {}", c.schema_name, c.message_encoding),
        });
    }
    Ok(())
}

/// Adds the keys not yet in `columns`, each right after the key that preceded
/// it in the message.
fn merge_columns<'a>(columns: &mut Vec<String>, keys: impl Iterator<Item = &'a str>) {
    let mut after = 0;
    for key in keys {
        match columns.iter().position(|c| c == key) {
            Some(i) => after = i + 1,
            None => {
                columns.insert(after, key.to_string());
                after += 1;
            }
        }
    }
}

/// A CSV cell.
#[derive(Clone, Debug, PartialEq)]
enum Cell {
    /// A number or boolean, written as is.
    Text(String),
    /// A string, quoted when needed.
    Str(String),
    /// `null`, an empty cell.
    Null,
}

fn write_row(out: &mut impl Write, cells: impl Iterator<Item = Option<Cell>>) -> std::io::Result<()> {
    for (i, cell) in cells.enumerate() {
        if i > 0 {
            out.write_all(b",")?;
        }
        match cell {
            Some(Cell::Text(s)) => out.write_all(s.as_bytes())?,
            Some(Cell::Str(s)) if s.contains([',', '"', '\n', '\r']) => {
                write!(out, "\"{}\"", s.replace('"', "\"\""))?;
            }
            Some(Cell::Str(s)) => out.write_all(s.as_bytes())?,
            Some(Cell::Null) | None => {}
        }
    }
    out.write_all(b"\n")
}

/// The leaves of a JSON message as `(dotted.path, cell)`, in document order.
fn flatten(path: &Path, m: &RawMessage, fields: &mut Vec<(String, Cell)>) -> Result<(), SessionError> {
    fields.clear();
    let mut de = serde_json::Deserializer::from_slice(&m.data);
    let result = Flatten { prefix: String::new(), out: fields }.deserialize(&mut de).and_then(|()| de.end());
    result.map_err(|source| SessionError::Decode {
        path: path.to_path_buf(),
        topic: m.topic().to_string(),
        log_time: m.log_time,
        source,
    })
}

struct Flatten<'a> {
    prefix: String,
    out: &'a mut Vec<(String, Cell)>,
}

impl Flatten<'_> {
    fn leaf<E>(self, cell: Cell) -> Result<(), E> {
        let key = if self.prefix.is_empty() { "value".to_string() } else { self.prefix };
        self.out.push((key, cell));
        Ok(())
    }

    fn child(&self, key: &str) -> String {
        if self.prefix.is_empty() { key.to_string() } else { format!("{}.{key}", self.prefix) }
    }
}

impl<'de> DeserializeSeed<'de> for Flatten<'_> {
    type Value = ();
    fn deserialize<D: de::Deserializer<'de>>(self, d: D) -> Result<(), D::Error> {
        d.deserialize_any(self)
    }
}

impl<'de> Visitor<'de> for Flatten<'_> {
    type Value = ();

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("a JSON value")
    }
    fn visit_bool<E>(self, v: bool) -> Result<(), E> {
        self.leaf(Cell::Text(v.to_string()))
    }
    fn visit_i64<E>(self, v: i64) -> Result<(), E> {
        self.leaf(Cell::Text(v.to_string()))
    }
    fn visit_u64<E>(self, v: u64) -> Result<(), E> {
        self.leaf(Cell::Text(v.to_string()))
    }
    fn visit_f64<E>(self, v: f64) -> Result<(), E> {
        // serde_json's shortest round-trip form (`1e-300`, not 300 zeros).
        let text = serde_json::Number::from_f64(v).map_or_else(String::new, |n| n.to_string());
        self.leaf(Cell::Text(text))
    }
    fn visit_str<E>(self, v: &str) -> Result<(), E> {
        self.leaf(Cell::Str(v.to_string()))
    }
    fn visit_unit<E>(self) -> Result<(), E> {
        self.leaf(Cell::Null)
    }
    fn visit_none<E>(self) -> Result<(), E> {
        self.leaf(Cell::Null)
    }
    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<(), A::Error> {
        let mut i = 0usize;
        loop {
            let prefix = self.child(&i.to_string());
            if seq.next_element_seed(Flatten { prefix, out: &mut *self.out })?.is_none() {
                break;
            }
            i += 1;
        }
        if i == 0 {
            return self.leaf(Cell::Null);
        }
        Ok(())
    }
    fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<(), A::Error> {
        while let Some(key) = map.next_key::<String>()? {
            let prefix = self.child(&key);
            map.next_value_seed(Flatten { prefix, out: &mut *self.out })?;
        }
        Ok(())
    }
}
