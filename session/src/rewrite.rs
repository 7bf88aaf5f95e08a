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

mod merge;

use std::collections::{BTreeMap, BTreeSet};
use std::fs::File;
use std::io::{BufWriter, Read};
use std::path::{Path, PathBuf};

use serde::Serialize;
use slidetrack_core::TimeNs;

use super::channel::{ChannelMessage, MESSAGE_ENCODING_JSON, SCHEMA_ENCODING_JSONSCHEMA};
use super::error::{ReplaceStep, SessionError, WriteFailure};
use super::reader::ReadOptions;
use super::records::{Payloads, Record, RecordStream, parse_header};
use super::scan::{footer_summary_start, open_session, truncated_error};
use merge::Merge;

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

/// One record to copy: the header (parsed), or any other record up to the
/// end of the data section.
enum Item {
    Header(mcap::records::Header),
    Record(Record),
}

/// The next record of `records` to copy; `Ok(None)` at the end of the data
/// section. Indexes, statistics and the summary are rebuilt by the writer.
fn next_item<R: Read>(path: &Path, records: &mut RecordStream<R>) -> Result<Option<Item>, SessionError> {
    match records.next_record().map_err(|e| e.into_session_error(path))? {
        None | Some(Record::DataEnd) => Ok(None),
        Some(Record::Header(body)) => parse_header(&body).map(|h| Some(Item::Header(h))).map_err(|source| {
            SessionError::Corrupt { path: path.to_path_buf(), bytes_read: records.bytes_read(), source }
        }),
        Some(record) => Ok(Some(Item::Record(record))),
    }
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
    let replace = |step| move |source| SessionError::Replace { path: path.to_path_buf(), step, source };
    temp.as_file().sync_all().map_err(replace(ReplaceStep::Sync))?;
    let permissions = std::fs::metadata(path).map_err(replace(ReplaceStep::ReadPermissions))?.permissions();
    std::fs::set_permissions(temp.path(), permissions).map_err(replace(ReplaceStep::SetPermissions))?;
    temp.persist(path).map_err(|e| replace(ReplaceStep::Rename)(e.error))?;
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
    let mut records = RecordStream::new(file, Payloads::None);
    let (mut count, mut truncated) = (0u64, false);
    let mut schemas = BTreeSet::new();
    let mut kept_schemas = BTreeSet::new();
    let mut schemas_of_dropped = BTreeSet::new();
    let mut dropped_channels = BTreeSet::new();
    let mut max_channel = None::<u32>;
    loop {
        let item = match next_item(path, &mut records) {
            Ok(Some(Item::Record(record))) => record,
            Ok(Some(Item::Header(_))) => {
                count += 1;
                continue;
            }
            Ok(None) => break,
            Err(_) if options.recover => {
                truncated = true;
                break;
            }
            Err(e) => return Err(e),
        };
        count += 1;
        match item {
            Record::Channel(c) if dropped(&c.topic) => {
                dropped_channels.insert(c.id);
                schemas_of_dropped.insert(c.schema_id);
            }
            Record::Channel(c) => {
                kept_schemas.insert(c.schema_id);
                max_channel = max_channel.max(Some(u32::from(c.id)));
            }
            Record::Schema { id, .. } => {
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
        let source = WriteFailure::from(e);
        SessionError::Write { path: path.to_path_buf(), kind: source.io_kind(), source }
    };
    let (file, _) = open_session(path)?;
    let mut records = RecordStream::new(file, Payloads::All);
    let mut writer: Option<Writer<'_>> = None;
    let mut merge = Merge::new(path, add, survey)?;
    let mut report = RewriteReport { truncated: survey.truncated, ..RewriteReport::default() };
    for _ in 0..survey.items {
        let Some(item) = next_item(path, &mut records)? else { break };
        let record = match (&mut writer, item) {
            (None, Item::Header(h)) => {
                writer = Some(new_writer(out, &h.profile, &h.library).map_err(fail)?);
                continue;
            }
            (Some(_), Item::Header(_)) => continue,
            (_, Item::Record(record)) => record,
        };
        let w = match &mut writer {
            Some(w) => w,
            None => writer.insert(new_writer(out, "", "").map_err(fail)?),
        };
        write_record(w, record, survey, &mut merge, &mut report).map_err(fail)?;
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

/// Copies one record unless its channel or schema is dropped, after the new
/// messages that come before it.
fn write_record(
    w: &mut Writer<'_>,
    record: Record,
    survey: &Survey,
    merge: &mut Merge,
    report: &mut RewriteReport,
) -> Result<(), mcap::McapError> {
    match record {
        Record::Header(_) | Record::DataEnd => {}
        Record::Schema { id, .. } if survey.dropped_schemas.contains(&id) => {}
        Record::Schema { id, name, encoding, data } => {
            w.add_schema_with_id(id, &name, &encoding, &data)?;
        }
        Record::Channel(c) if survey.dropped_channels.contains(&c.id) => {}
        Record::Channel(c) => {
            w.add_channel_with_id(c.id, c.schema_id, &c.topic, &c.message_encoding, &c.metadata)?;
        }
        Record::Message { header, .. } if survey.dropped_channels.contains(&header.channel_id) => {
            report.messages_dropped += 1;
        }
        Record::Message { header, data } => {
            report.messages_added += merge.write_before(w, TimeNs(header.log_time))?;
            w.write_to_known_channel(&header, &data)?;
            report.messages_copied += 1;
        }
        Record::Attachment(a) => w.attach(&a)?,
        Record::Metadata(m) => w.write_metadata(&m)?,
    }
    Ok(())
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

#[cfg(test)]
mod tests;
