//! Rewriting a finished session in place, atomically: every record is
//! copied unchanged (header, schemas, channels with their ids, messages with
//! their times, sequence numbers and payload bytes, attachments, metadata, in
//! file order) except the channels being replaced; new channels are merged in
//! by log time. The result goes to a temporary file in the same directory,
//! is synced, and renamed over the original. On any error the temporary file
//! is removed and the original is left as it was.
//!
//! The output depends only on the kept records and the new channels, so
//! rewriting a file twice with the same new channels gives the same bytes.

use std::borrow::Cow;
use std::collections::{BTreeMap, BTreeSet, VecDeque};
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

use mcap::records::{self, MessageHeader, Metadata, Record, op};
use mcap::sans_io::{LinearReadEvent, LinearReader, LinearReaderOptions};
use serde::Serialize;
use slidetrack_core::TimeNs;

use super::error::SessionError;
use super::messages::{ChannelMessage, MESSAGE_ENCODING_JSON, SCHEMA_ENCODING_JSONSCHEMA};
use super::reader::ReadOptions;
use super::scan::{
    RECORD_LENGTH_LIMIT, chunk_reader, footer_summary_start, open_session, read_full, truncated_error,
};

/// The most bytes read from the file at once.
const READ_BLOCK: usize = 1 << 20;
/// Chunks of the rewritten file close at this uncompressed size (bytes), as the recorder's do.
const CHUNK_SIZE_BYTES: u64 = 4 << 20;

/// A message of a channel added by [`rewrite_session`].
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct NewMessage {
    /// Log time on the session clock.
    pub log_time: TimeNs,
    /// Publish time (the log time when there is no device time).
    pub publish_time: TimeNs,
    /// Sequence number.
    pub sequence: u32,
    /// The payload.
    pub data: Vec<u8>,
}

/// A channel added by [`rewrite_session`], with all its messages.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct NewChannel {
    /// Topic; an existing channel on it is replaced.
    pub topic: String,
    /// Schema name (empty with `schema_encoding` for no schema).
    pub schema_name: String,
    /// Schema encoding.
    pub schema_encoding: String,
    /// Schema bytes.
    pub schema: Vec<u8>,
    /// Message encoding.
    pub message_encoding: String,
    /// Channel metadata.
    pub metadata: BTreeMap<String, String>,
    /// The messages, in log-time order (sorted stably before writing).
    pub messages: Vec<NewMessage>,
}

impl NewChannel {
    /// An empty channel for `T` (JSON messages, JSON Schema).
    pub fn of<T: ChannelMessage>(metadata: BTreeMap<String, String>) -> NewChannel {
        NewChannel {
            topic: T::TOPIC.to_string(),
            schema_name: T::SCHEMA_NAME.to_string(),
            schema_encoding: SCHEMA_ENCODING_JSONSCHEMA.to_string(),
            schema: T::json_schema().to_string().into_bytes(),
            message_encoding: MESSAGE_ENCODING_JSON.to_string(),
            metadata,
            messages: Vec::new(),
        }
    }

    /// Appends `message` as JSON at `log_time` (also its publish time, sequence 0).
    pub fn push_json<T: Serialize>(
        &mut self,
        log_time: TimeNs,
        message: &T,
    ) -> Result<(), serde_json::Error> {
        let data = serde_json::to_vec(message)?;
        self.messages.push(NewMessage { log_time, publish_time: log_time, sequence: 0, data });
        Ok(())
    }
}

/// What a rewrite did.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct RewriteReport {
    /// Messages copied unchanged.
    pub messages_copied: u64,
    /// Messages of replaced channels left out.
    pub messages_dropped: u64,
    /// Messages of the new channels written.
    pub messages_added: u64,
    /// The input was truncated and only its complete chunks were kept (with `recover`).
    pub truncated: bool,
}

/// One record of the input, owned.
enum Item {
    Header(records::Header),
    Schema { id: u16, name: String, encoding: String, data: Vec<u8> },
    Channel(records::Channel),
    Message { header: MessageHeader, data: Vec<u8> },
    Attachment(mcap::Attachment<'static>),
    Metadata(Metadata),
}

/// Replaces the channels whose topic `drop` accepts (and those on the topics
/// of `add`) by the channels of `add`, rewriting `path` atomically.
///
/// # Contract
/// - Without `options.recover`, a truncated or corrupt input fails before
///   anything is written. With it, the complete chunks of a truncated file
///   are kept and the output is a complete file.
/// - Kept schemas and channels keep their ids; new ones get ids above the
///   largest kept id. A schema used only by dropped channels is dropped.
/// - New messages go before the first kept message with a larger log time.
/// - The file's permissions are kept. On error the original is untouched.
pub fn rewrite_session(
    path: impl AsRef<Path>,
    options: ReadOptions,
    drop: &dyn Fn(&str) -> bool,
    mut add: Vec<NewChannel>,
) -> Result<RewriteReport, SessionError> {
    let path = path.as_ref();
    let replaced: BTreeSet<String> = add.iter().map(|c| c.topic.clone()).collect();
    let dropped = |topic: &str| drop(topic) || replaced.contains(topic);
    let survey = survey(path, options, &dropped)?;
    for channel in &mut add {
        channel.messages.sort_by_key(|m| m.log_time);
    }
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let name = path.file_name().map_or_else(|| "session".into(), |n| n.to_string_lossy().into_owned());
    let temp = tempfile::Builder::new()
        .prefix(&format!(".{name}."))
        .suffix(".tmp")
        .tempfile_in(&dir)
        .map_err(|source| SessionError::Create { path: dir.join(format!(".{name}.*.tmp")), source })?;
    let report = copy(path, temp.as_file(), &survey, add)?;
    let write_err = |kind, detail: String| SessionError::Write { path: path.to_path_buf(), kind, detail };
    let io_err = |e: std::io::Error, what: &str| write_err(Some(e.kind()), format!("{what}: {e}"));
    temp.as_file().sync_all().map_err(|e| io_err(e, "sync of the rewritten file"))?;
    let permissions =
        std::fs::metadata(path).map_err(|e| io_err(e, "cannot read permissions"))?.permissions();
    std::fs::set_permissions(temp.path(), permissions).map_err(|e| io_err(e, "cannot set permissions"))?;
    temp.persist(path).map_err(|e| io_err(e.error, "cannot replace the original"))?;
    if let Ok(d) = File::open(&dir) {
        // Makes the rename durable; not all file systems allow it.
        let _ = d.sync_all();
    }
    Ok(report)
}

/// What the first pass learned.
struct Survey {
    /// Records to copy (all, or those before the corrupt part with `recover`).
    items: u64,
    truncated: bool,
    dropped_channels: BTreeSet<u16>,
    dropped_schemas: BTreeSet<u16>,
    next_schema_id: u32,
    next_channel_id: u32,
}

/// Reads the whole input once: checks it, and finds the ids in use.
fn survey(path: &Path, options: ReadOptions, dropped: &dyn Fn(&str) -> bool) -> Result<Survey, SessionError> {
    let (mut file, size) = open_session(path)?;
    let complete = footer_summary_start(&mut file, size)
        .map_err(|source| SessionError::Read { path: path.to_path_buf(), source })?
        .is_some();
    if !complete && !options.recover {
        return Err(truncated_error(path, file));
    }
    let mut items = Items::new(path, file);
    let (mut count, mut truncated) = (0u64, false);
    let mut schemas = BTreeSet::new();
    let mut kept_schemas = BTreeSet::new();
    let mut schemas_of_dropped = BTreeSet::new();
    let mut dropped_channels = BTreeSet::new();
    let mut max_channel = None::<u32>;
    loop {
        let item = match items.next_item() {
            Ok(Some(item)) => item,
            Ok(None) => break,
            Err(_) if options.recover => {
                truncated = true;
                break;
            }
            Err(e) => return Err(e),
        };
        count += 1;
        match item {
            Item::Channel(c) if dropped(&c.topic) => {
                dropped_channels.insert(c.id);
                schemas_of_dropped.insert(c.schema_id);
            }
            Item::Channel(c) => {
                kept_schemas.insert(c.schema_id);
                max_channel = max_channel.max(Some(u32::from(c.id)));
            }
            Item::Schema { id, .. } => {
                schemas.insert(id);
            }
            _ => {}
        }
    }
    let dropped_schemas: BTreeSet<u16> = schemas_of_dropped.difference(&kept_schemas).copied().collect();
    let max_kept_schema = schemas.difference(&dropped_schemas).max().map_or(0, |&id| u32::from(id));
    Ok(Survey {
        items: count,
        truncated: truncated || !complete,
        dropped_channels,
        next_schema_id: max_kept_schema + 1,
        next_channel_id: max_channel.map_or(0, |c| c + 1),
        dropped_schemas,
    })
}

type Writer<'a> = mcap::Writer<BufWriter<&'a File>>;

/// Writes the merged file into `out`.
fn copy(
    path: &Path,
    out: &File,
    survey: &Survey,
    add: Vec<NewChannel>,
) -> Result<RewriteReport, SessionError> {
    let fail = |e: mcap::McapError| {
        let kind = match &e {
            mcap::McapError::Io(io) => Some(io.kind()),
            _ => None,
        };
        SessionError::Write { path: path.to_path_buf(), kind, detail: format!("rewriting: {e}") }
    };
    let (file, _) = open_session(path)?;
    let mut items = Items::new(path, file);
    let mut writer: Option<Writer<'_>> = None;
    let mut merge = Merge::new(path, add, survey)?;
    let mut report = RewriteReport { truncated: survey.truncated, ..RewriteReport::default() };
    for _ in 0..survey.items {
        let Some(item) = items.next_item()? else { break };
        let w = match (&mut writer, &item) {
            (Some(w), _) => w,
            (None, Item::Header(h)) => {
                writer = Some(new_writer(out, &h.profile, &h.library).map_err(fail)?);
                continue;
            }
            (None, _) => writer.insert(new_writer(out, "", "").map_err(fail)?),
        };
        match item {
            Item::Header(_) => {}
            Item::Schema { id, .. } if survey.dropped_schemas.contains(&id) => {}
            Item::Schema { id, name, encoding, data } => {
                w.add_schema_with_id(id, &name, &encoding, &data).map_err(fail)?;
            }
            Item::Channel(c) if survey.dropped_channels.contains(&c.id) => {}
            Item::Channel(c) => {
                w.add_channel_with_id(c.id, c.schema_id, &c.topic, &c.message_encoding, &c.metadata)
                    .map_err(fail)?;
            }
            Item::Message { header, .. } if survey.dropped_channels.contains(&header.channel_id) => {
                report.messages_dropped += 1;
            }
            Item::Message { header, data } => {
                report.messages_added += merge.write_before(w, TimeNs(header.log_time)).map_err(fail)?;
                w.write_to_known_channel(&header, &data).map_err(fail)?;
                report.messages_copied += 1;
            }
            Item::Attachment(a) => w.attach(&a).map_err(fail)?,
            Item::Metadata(m) => w.write_metadata(&m).map_err(fail)?,
        }
    }
    let w = match &mut writer {
        Some(w) => w,
        None => writer.insert(new_writer(out, "", "").map_err(fail)?),
    };
    report.messages_added += merge.write_before(w, TimeNs(u64::MAX)).map_err(fail)?;
    merge.declare_empty(w).map_err(fail)?;
    if let Some(mut w) = writer {
        w.finish().map_err(fail)?;
        let buffered = w.into_inner();
        buffered.into_inner().map_err(|e| fail(mcap::McapError::Io(e.into_error())))?;
    }
    Ok(report)
}

fn new_writer<'a>(out: &'a File, profile: &str, library: &str) -> Result<Writer<'a>, mcap::McapError> {
    let options = mcap::WriteOptions::new()
        .compression(Some(mcap::Compression::Zstd))
        .compression_level(1)
        .compression_threads(0)
        .chunk_size(Some(CHUNK_SIZE_BYTES))
        .profile(profile)
        .library(library);
    mcap::Writer::with_options(BufWriter::with_capacity(256 << 10, out), options)
}

/// The new channels, written in log-time order among the copied messages.
struct Merge {
    channels: Vec<(NewChannel, u16, u16, bool)>,
    /// Next message per channel.
    cursor: Vec<usize>,
}

impl Merge {
    fn new(path: &Path, add: Vec<NewChannel>, survey: &Survey) -> Result<Merge, SessionError> {
        let mut channels = Vec::with_capacity(add.len());
        for (k, channel) in add.into_iter().enumerate() {
            let k = k as u32;
            let schema_id = u16::try_from(survey.next_schema_id + k);
            let channel_id = u16::try_from(survey.next_channel_id + k);
            let (Ok(schema_id), Ok(channel_id)) = (schema_id, channel_id) else {
                return Err(SessionError::Channel {
                    path: path.to_path_buf(),
                    topic: channel.topic,
                    detail: "no free schema or channel id".into(),
                });
            };
            channels.push((channel, schema_id, channel_id, false));
        }
        let cursor = vec![0; channels.len()];
        Ok(Merge { channels, cursor })
    }

    /// Writes every pending new message with a log time before `t`, oldest
    /// first (ties in the order of the channels); returns how many.
    fn write_before(&mut self, w: &mut Writer<'_>, t: TimeNs) -> Result<u64, mcap::McapError> {
        let mut written = 0;
        loop {
            let next = (0..self.channels.len())
                .filter_map(|k| self.channels[k].0.messages.get(self.cursor[k]).map(|m| (m.log_time, k)))
                .filter(|(log_time, _)| *log_time < t)
                .min();
            let Some((_, k)) = next else { return Ok(written) };
            Self::declare(w, &mut self.channels[k])?;
            let (channel, _, channel_id, _) = &self.channels[k];
            let m = &channel.messages[self.cursor[k]];
            let header = MessageHeader {
                channel_id: *channel_id,
                sequence: m.sequence,
                log_time: m.log_time.0,
                publish_time: m.publish_time.0,
            };
            w.write_to_known_channel(&header, &m.data)?;
            self.cursor[k] += 1;
            written += 1;
        }
    }

    /// Declares the channels that had no message.
    fn declare_empty(&mut self, w: &mut Writer<'_>) -> Result<(), mcap::McapError> {
        self.channels.iter_mut().try_for_each(|c| Self::declare(w, c))
    }

    fn declare(w: &mut Writer<'_>, entry: &mut (NewChannel, u16, u16, bool)) -> Result<(), mcap::McapError> {
        let (c, schema_id, channel_id, declared) = entry;
        if !*declared {
            let schema_id = if c.schema_name.is_empty() && c.schema_encoding.is_empty() {
                0
            } else {
                w.add_schema_with_id(*schema_id, &c.schema_name, &c.schema_encoding, &c.schema)?
            };
            w.add_channel_with_id(*channel_id, schema_id, &c.topic, &c.message_encoding, &c.metadata)?;
            *declared = true;
        }
        Ok(())
    }
}

/// The records of a file in order, chunks opened, with bounded memory (one
/// chunk at a time). A chunk's records are handed out only once the whole
/// chunk has been read and its CRC checked.
struct Items {
    path: PathBuf,
    input: File,
    reader: LinearReader,
    bytes_read: u64,
    pending: VecDeque<Item>,
}

impl Items {
    fn new(path: &Path, input: File) -> Items {
        let options = LinearReaderOptions::default()
            .with_emit_chunks(true)
            .with_validate_data_section_crc(true)
            .with_record_length_limit(RECORD_LENGTH_LIMIT);
        Items {
            path: path.to_path_buf(),
            input,
            reader: LinearReader::new_with_options(options),
            bytes_read: 0,
            pending: VecDeque::new(),
        }
    }

    fn corrupt(&self, detail: String) -> SessionError {
        SessionError::Corrupt { path: self.path.clone(), bytes_read: self.bytes_read, detail }
    }

    /// The next record to copy; `Ok(None)` at the end of the data.
    fn next_item(&mut self) -> Result<Option<Item>, SessionError> {
        loop {
            if let Some(item) = self.pending.pop_front() {
                return Ok(Some(item));
            }
            let (opcode, data) = match self.reader.next_event() {
                None => return Ok(None),
                Some(Err(e)) => return Err(self.corrupt(e.to_string())),
                Some(Ok(LinearReadEvent::ReadRequest(need))) => {
                    let buf = self.reader.insert(need.clamp(1, READ_BLOCK));
                    let n = read_full(&mut self.input, buf);
                    let n = match n {
                        Ok(n) => n,
                        Err(source) => {
                            self.reader.notify_read(0);
                            return Err(SessionError::Read { path: self.path.clone(), source });
                        }
                    };
                    self.reader.notify_read(n);
                    self.bytes_read += n as u64;
                    continue;
                }
                Some(Ok(LinearReadEvent::Record { opcode, data })) => (opcode, data.to_vec()),
            };
            match opcode {
                op::CHUNK => self.open_chunk(&data)?,
                op::DATA_END => return Ok(None),
                _ => {
                    if let Some(item) = self.parse(opcode, &data)? {
                        self.pending.push_back(item);
                    }
                }
            }
        }
    }

    /// Decompresses a chunk (checking its CRC first) and queues its records.
    fn open_chunk(&mut self, data: &[u8]) -> Result<(), SessionError> {
        let mut inner = chunk_reader(data);
        let mut queued = VecDeque::new();
        let mut eof_sent = false;
        while let Some(event) = inner.next_event() {
            match event {
                Ok(LinearReadEvent::ReadRequest(_)) if !eof_sent => {
                    inner.notify_read(0);
                    eof_sent = true;
                }
                Ok(LinearReadEvent::ReadRequest(_)) => return Err(self.corrupt("chunk ends early".into())),
                Ok(LinearReadEvent::Record { opcode, data }) => {
                    if let Some(item) = self.parse(opcode, data)? {
                        queued.push_back(item);
                    }
                }
                Err(e) => return Err(self.corrupt(format!("bad chunk: {e}"))),
            }
        }
        self.pending.extend(queued);
        Ok(())
    }

    /// The records that are copied; indexes, statistics and the summary are
    /// rebuilt by the writer.
    fn parse(&self, opcode: u8, data: &[u8]) -> Result<Option<Item>, SessionError> {
        let bad = |e: &dyn std::fmt::Display| self.corrupt(format!("bad record {opcode:#04x}: {e}"));
        if opcode == op::ATTACHMENT {
            return parse_attachment(data)
                .map(|a| Some(Item::Attachment(a)))
                .ok_or_else(|| bad(&"attachment"));
        }
        if !matches!(opcode, op::HEADER | op::SCHEMA | op::CHANNEL | op::MESSAGE | op::METADATA) {
            return Ok(None);
        }
        Ok(match mcap::parse_record(opcode, data).map_err(|e| bad(&e))? {
            Record::Header(h) => Some(Item::Header(h)),
            Record::Schema { header, data } => Some(Item::Schema {
                id: header.id,
                name: header.name,
                encoding: header.encoding,
                data: data.into_owned(),
            }),
            Record::Channel(c) => Some(Item::Channel(c)),
            Record::Message { header, data } => Some(Item::Message { header, data: data.into_owned() }),
            Record::Metadata(m) => Some(Item::Metadata(m)),
            _ => None,
        })
    }
}

/// An attachment record, parsed by hand (the `mcap` parser can panic on a
/// malformed one): times, name, media type, data; the CRC is recomputed on write.
fn parse_attachment(body: &[u8]) -> Option<mcap::Attachment<'static>> {
    fn string(buf: &[u8]) -> Option<(String, &[u8])> {
        let (len, rest) = buf.split_first_chunk::<4>()?;
        let len = u32::from_le_bytes(*len) as usize;
        let s = std::str::from_utf8(rest.get(..len)?).ok()?;
        Some((s.to_string(), rest.get(len..)?))
    }
    let (log_time, rest) = body.split_first_chunk::<8>()?;
    let (create_time, rest) = rest.split_first_chunk::<8>()?;
    let (name, rest) = string(rest)?;
    let (media_type, rest) = string(rest)?;
    let (len, rest) = rest.split_first_chunk::<8>()?;
    let len = usize::try_from(u64::from_le_bytes(*len)).ok()?;
    let data = rest.get(..len)?;
    (rest.len() == len.checked_add(4)?).then(|| mcap::Attachment {
        log_time: u64::from_le_bytes(*log_time),
        create_time: u64::from_le_bytes(*create_time),
        name,
        media_type,
        data: Cow::Owned(data.to_vec()),
    })
}

#[cfg(test)]
mod tests;
