//! What a session file holds, from its summary section when it has one, else
//! from a scan of the whole file.

use std::collections::{BTreeMap, HashMap};
use std::fs::File;
use std::io::{Seek, SeekFrom};
use std::path::{Path, PathBuf};
use std::time::Duration;

use mcap::records::{ChunkIndex, Record, op};
use slidetrack_core::TimeNs;

use super::error::SessionError;
use super::metadata::{OUTCOME_METADATA, SESSION_METADATA, SessionMetadata, SessionOutcome};
use super::reader::{ChannelDesc, ReadOptions};
use super::scan::{
    Event, FOOTER_AND_MAGIC, RECORD_LENGTH_LIMIT, Scanner, corrupt, footer_summary_start, open_session,
    raw_records, read_full,
};

/// One channel of a session.
#[derive(Clone, Debug, PartialEq)]
pub struct ChannelSummary {
    /// The channel's topic.
    pub topic: String,
    /// Schema name (`slidetrack.TactileRaw`), empty when there is none.
    pub schema_name: String,
    /// Message encoding (`json`).
    pub message_encoding: String,
    /// Channel metadata.
    pub metadata: BTreeMap<String, String>,
    /// Messages on the channel.
    pub message_count: u64,
    /// Log time of its first message.
    pub first_log_time: Option<TimeNs>,
    /// Log time of its last message.
    pub last_log_time: Option<TimeNs>,
    /// `(count - 1) / (last - first)` (Hz), `None` with fewer than two
    /// messages or no time between them.
    pub mean_rate_hz: Option<f64>,
}

/// An attachment of a session.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct AttachmentSummary {
    /// Its name (a file name).
    pub name: String,
    /// Its media type (`application/toml`).
    pub media_type: String,
    /// Its size (bytes).
    pub size_bytes: u64,
}

/// What a session file holds.
#[derive(Clone, Debug, PartialEq)]
pub struct SessionInfo {
    /// The file.
    pub path: PathBuf,
    /// Its size (bytes).
    pub file_size_bytes: u64,
    /// Channels, by channel id.
    pub channels: Vec<ChannelSummary>,
    /// Messages on all channels.
    pub message_count: u64,
    /// Log time of the first message.
    pub start: Option<TimeNs>,
    /// Log time of the last message.
    pub end: Option<TimeNs>,
    /// `end - start`.
    pub duration: Duration,
    /// Metadata records by name (the last one wins when a name repeats).
    pub metadata: BTreeMap<String, BTreeMap<String, String>>,
    /// Attachments, in file order.
    pub attachments: Vec<AttachmentSummary>,
    /// Complete chunks.
    pub chunk_count: u64,
    /// True when the file was cut short (read with `recover`): everything
    /// above describes its complete chunks only.
    pub truncated: bool,
}

impl SessionInfo {
    /// Reads what `path` holds: from the summary section when there is one
    /// (fast), else by scanning the file.
    ///
    /// Without `options.recover` a file cut short fails with
    /// [`SessionError::Truncated`]; with it, the result describes the
    /// complete chunks and has `truncated` set.
    pub fn read(path: impl AsRef<Path>, options: ReadOptions) -> Result<SessionInfo, SessionError> {
        let path = path.as_ref();
        let (mut file, size) = open_session(path)?;
        let read_err = |source| SessionError::Read { path: path.to_path_buf(), source };
        let summary_start = footer_summary_start(&mut file, size).map_err(read_err)?;
        if let Some(start) = summary_start.filter(|&s| s != 0) {
            match from_summary(path, &mut file, size, start) {
                Ok(Some(info)) => return Ok(info),
                Ok(None) => {}
                Err(e) if !options.recover => return Err(e),
                Err(e) => tracing::debug!("{e}; scanning the file instead"),
            }
            file.seek(SeekFrom::Start(0)).map_err(read_err)?;
        }
        scan_info(path, file, size, summary_start.is_some(), options)
    }

    /// The channel on `topic`.
    pub fn channel(&self, topic: &str) -> Option<&ChannelSummary> {
        self.channels.iter().find(|c| c.topic == topic)
    }

    /// The `slidetrack` metadata record, if present and well-formed.
    pub fn session_metadata(&self) -> Option<SessionMetadata> {
        self.metadata.get(SESSION_METADATA).and_then(SessionMetadata::from_map)
    }

    /// The `slidetrack.outcome` metadata record, if present and well-formed.
    pub fn outcome(&self) -> Option<SessionOutcome> {
        self.metadata.get(OUTCOME_METADATA).and_then(SessionOutcome::from_map)
    }
}

/// Per-channel counts and times, filled while reading.
#[derive(Default)]
struct ChannelTally {
    count: u64,
    first: Option<TimeNs>,
    last: Option<TimeNs>,
}

impl ChannelTally {
    fn add(&mut self, t: TimeNs) {
        self.count += 1;
        self.first = Some(self.first.map_or(t, |f| f.min(t)));
        self.last = Some(self.last.map_or(t, |l| l.max(t)));
    }
}

fn channel_summary(desc: &ChannelDesc, tally: Option<&ChannelTally>) -> ChannelSummary {
    let (count, first, last) = tally.map_or((0, None, None), |t| (t.count, t.first, t.last));
    let mean_rate_hz = match (first, last) {
        (Some(f), Some(l)) if count >= 2 && l > f => Some((count - 1) as f64 / l.secs_since(f)),
        _ => None,
    };
    ChannelSummary {
        topic: desc.topic.clone(),
        schema_name: desc.schema_name.clone(),
        message_encoding: desc.message_encoding.clone(),
        metadata: desc.metadata.clone(),
        message_count: count,
        first_log_time: first,
        last_log_time: last,
        mean_rate_hz,
    }
}

#[expect(clippy::too_many_arguments, reason = "the parts of a summary, each read from its own record")]
fn assemble(
    path: &Path,
    file_size_bytes: u64,
    channels: &[ChannelDesc],
    tallies: &HashMap<u16, ChannelTally>,
    metadata: BTreeMap<String, BTreeMap<String, String>>,
    attachments: Vec<AttachmentSummary>,
    chunk_count: u64,
    truncated: bool,
) -> SessionInfo {
    let channels: Vec<ChannelSummary> =
        channels.iter().map(|c| channel_summary(c, tallies.get(&c.id))).collect();
    let start = channels.iter().filter_map(|c| c.first_log_time).min();
    let end = channels.iter().filter_map(|c| c.last_log_time).max();
    let duration = match (start, end) {
        (Some(s), Some(e)) => e - s,
        _ => Duration::ZERO,
    };
    SessionInfo {
        path: path.to_path_buf(),
        file_size_bytes,
        message_count: channels.iter().map(|c| c.message_count).sum(),
        channels,
        start,
        end,
        duration,
        metadata,
        attachments,
        chunk_count,
        truncated,
    }
}

/// Scans the whole file. `has_footer` tells a truncated file (no footer) from
/// a corrupt one.
pub(crate) fn scan_info(
    path: &Path,
    file: File,
    size: u64,
    has_footer: bool,
    options: ReadOptions,
) -> Result<SessionInfo, SessionError> {
    let mut scan = Scanner::new(path, file, None, false);
    let mut tallies: HashMap<u16, ChannelTally> = HashMap::new();
    let mut metadata = BTreeMap::new();
    let mut attachments = Vec::new();
    let mut truncated = false;
    loop {
        match scan.next_event() {
            Ok(Some(Event::Message(m))) => tallies.entry(m.channel.id).or_default().add(m.log_time),
            Ok(Some(Event::Metadata { name, map })) => {
                metadata.insert(name, map);
            }
            Ok(Some(Event::Attachment(a))) => attachments.push(a),
            Ok(None) => break,
            Err(e) if !options.recover && has_footer => return Err(corrupt(path, e)),
            Err(e) if !options.recover => {
                return Err(match e.io {
                    Some(source) => SessionError::Read { path: path.to_path_buf(), source },
                    None => SessionError::Truncated {
                        path: path.to_path_buf(),
                        readable_messages: scan.messages,
                        complete_chunks: scan.complete_chunks,
                        readable_until: scan.last_log_time,
                    },
                });
            }
            Err(_) => {
                truncated = true;
                break;
            }
        }
    }
    let channels: Vec<ChannelDesc> = scan.channels.values().map(|c| c.as_ref().clone()).collect();
    let chunks = scan.complete_chunks;
    Ok(assemble(path, size, &channels, &tallies, metadata, attachments, chunks, truncated))
}

/// Reads `len` bytes at `offset`, refusing lengths beyond the record limit or the file.
fn read_at(file: &mut File, size: u64, offset: u64, len: u64) -> Option<Vec<u8>> {
    if len > RECORD_LENGTH_LIMIT as u64 || offset.checked_add(len)? > size {
        return None;
    }
    let mut buf = vec![0u8; len as usize];
    file.seek(SeekFrom::Start(offset)).ok()?;
    (read_full(file, &mut buf).ok()? == buf.len()).then_some(buf)
}

/// The info from the summary section, `Ok(None)` when the summary lacks what
/// is needed (statistics, message indexes) and the file must be scanned.
fn from_summary(
    path: &Path,
    file: &mut File,
    size: u64,
    summary_start: u64,
) -> Result<Option<SessionInfo>, SessionError> {
    let corrupt = |detail: &str| SessionError::Corrupt {
        path: path.to_path_buf(),
        bytes_read: summary_start,
        detail: format!("bad summary section: {detail}"),
    };
    let footer_start = size - FOOTER_AND_MAGIC;
    let len = footer_start.checked_sub(summary_start).ok_or_else(|| corrupt("starts after the footer"))?;
    let summary = read_at(file, size, summary_start, len).ok_or_else(|| corrupt("unreadable"))?;

    let mut schemas: HashMap<u16, (String, String)> = HashMap::new();
    let mut channels: Vec<ChannelDesc> = Vec::new();
    let mut stats = None;
    let mut chunk_indexes: Vec<ChunkIndex> = Vec::new();
    let mut metadata_indexes = Vec::new();
    let mut attachments = Vec::new();
    for record in raw_records(&summary) {
        let (opcode, body) = record.map_err(|()| corrupt("a record runs past its end"))?;
        let parsed = match opcode {
            op::SCHEMA
            | op::CHANNEL
            | op::STATISTICS
            | op::CHUNK_INDEX
            | op::ATTACHMENT_INDEX
            | op::METADATA_INDEX => mcap::parse_record(opcode, body).map_err(|e| corrupt(&e.to_string()))?,
            _ => continue,
        };
        match parsed {
            Record::Schema { header, .. } => {
                schemas.insert(header.id, (header.name, header.encoding));
            }
            Record::Channel(c) => {
                let (schema_name, schema_encoding) = schemas.get(&c.schema_id).cloned().unwrap_or_default();
                channels.push(ChannelDesc {
                    id: c.id,
                    topic: c.topic,
                    schema_name,
                    schema_encoding,
                    message_encoding: c.message_encoding,
                    metadata: c.metadata,
                });
            }
            Record::Statistics(s) => stats = Some(s),
            Record::ChunkIndex(c) => chunk_indexes.push(c),
            Record::AttachmentIndex(a) => attachments.push(super::AttachmentSummary {
                name: a.name,
                media_type: a.media_type,
                size_bytes: a.data_size,
            }),
            Record::MetadataIndex(m) => metadata_indexes.push(m),
            _ => {}
        }
    }
    let Some(stats) = stats else { return Ok(None) };
    channels.sort_by_key(|c| c.id);

    // Per-channel first and last log times, from the message indexes after each chunk.
    let mut tallies: HashMap<u16, ChannelTally> = HashMap::new();
    for chunk in &chunk_indexes {
        if chunk.message_index_offsets.is_empty() && chunk.message_index_length == 0 {
            return Ok(None);
        }
        let offset = chunk.chunk_start_offset.checked_add(chunk.chunk_length);
        let indexes = offset.and_then(|o| read_at(file, size, o, chunk.message_index_length));
        let indexes = indexes.ok_or_else(|| corrupt("unreadable message index"))?;
        for record in raw_records(&indexes) {
            let (opcode, body) = record.map_err(|()| corrupt("bad message index"))?;
            if opcode != op::MESSAGE_INDEX {
                continue;
            }
            if let Ok(Record::MessageIndex(index)) = mcap::parse_record(opcode, body) {
                let tally = tallies.entry(index.channel_id).or_default();
                index.records.iter().for_each(|e| tally.add(TimeNs(e.log_time)));
            }
        }
    }
    let indexed: u64 = tallies.values().map(|t| t.count).sum();
    if indexed != stats.message_count {
        return Ok(None);
    }

    let mut metadata = BTreeMap::new();
    for index in &metadata_indexes {
        let record =
            read_at(file, size, index.offset, index.length).ok_or_else(|| corrupt("unreadable metadata"))?;
        let parsed = raw_records(&record).next().and_then(Result::ok);
        match parsed.map(|(opcode, body)| (opcode, mcap::parse_record(opcode, body))) {
            Some((op::METADATA, Ok(Record::Metadata(m)))) => {
                metadata.insert(m.name, m.metadata);
            }
            _ => return Err(corrupt("a metadata index points at no metadata record")),
        }
    }
    let chunks = u64::from(stats.chunk_count);
    Ok(Some(assemble(path, size, &channels, &tallies, metadata, attachments, chunks, false)))
}
