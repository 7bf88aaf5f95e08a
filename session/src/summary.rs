//! What a session file holds, from its summary section when it has one, else
//! from a scan of the whole file.

mod indexed;

use std::collections::{BTreeMap, HashMap};
use std::io::{Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};
use std::time::Duration;

use slidetrack_core::TimeNs;

use super::error::{SessionError, error_chain};
use super::metadata::{OUTCOME_METADATA, SESSION_METADATA, SessionMetadata, SessionOutcome};
use super::reader::ReadOptions;
use super::records::StreamError;
use super::scan::{Event, Scanner, check_session, footer_summary_start, open_session};
use super::stored::{AttachmentSummary, ChannelDesc};

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
        let (file, size) = open_session(path)?;
        read_info(path, file, size, options)
    }

    /// [`SessionInfo::read`] of the session held by `input` (from its start,
    /// for example a `Cursor` over the bytes of a file); `name` stands for the
    /// file in errors and in [`SessionInfo::path`].
    pub fn from_reader(
        name: impl AsRef<Path>,
        mut input: impl Read + Seek,
        options: ReadOptions,
    ) -> Result<SessionInfo, SessionError> {
        let name = name.as_ref();
        let size = check_session(name, &mut input)?;
        read_info(name, input, size, options)
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

/// What a [`SessionInfo`] is made of, read from the summary section or by a scan.
struct Parts {
    /// Channels, by id.
    channels: Vec<ChannelDesc>,
    /// Counts and times per channel id.
    tallies: HashMap<u16, ChannelTally>,
    /// Metadata records by name.
    metadata: BTreeMap<String, BTreeMap<String, String>>,
    /// Attachments, in file order.
    attachments: Vec<AttachmentSummary>,
    /// Complete chunks.
    chunk_count: u64,
}

impl Parts {
    fn assemble(self, path: &Path, file_size_bytes: u64, truncated: bool) -> SessionInfo {
        let tallies = &self.tallies;
        let channels: Vec<ChannelSummary> =
            self.channels.iter().map(|c| channel_summary(c, tallies.get(&c.id))).collect();
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
            metadata: self.metadata,
            attachments: self.attachments,
            chunk_count: self.chunk_count,
            truncated,
        }
    }
}

/// Reads what the session in `input` (of `size` bytes) holds: from its
/// summary section when there is one and it has what is needed, else by
/// scanning the file.
fn read_info<R: Read + Seek>(
    path: &Path,
    mut input: R,
    size: u64,
    options: ReadOptions,
) -> Result<SessionInfo, SessionError> {
    let read_err = |source| SessionError::Read { path: path.to_path_buf(), source };
    let summary_start = footer_summary_start(&mut input, size).map_err(read_err)?;
    if let Some(start) = summary_start.filter(|&s| s != 0) {
        match indexed::from_summary(path, &mut input, size, start) {
            Ok(Some(info)) => return Ok(info),
            Ok(None) => {}
            Err(e) if !options.recover => return Err(e),
            Err(e) => tracing::debug!("{}; scanning the file instead", error_chain(&e)),
        }
        input.seek(SeekFrom::Start(0)).map_err(read_err)?;
    }
    scan_info(path, input, size, summary_start.is_some(), options)
}

/// Scans the whole file. `has_footer` tells a truncated file (no footer) from
/// a corrupt one.
pub(crate) fn scan_info<R: Read>(
    path: &Path,
    input: R,
    size: u64,
    has_footer: bool,
    options: ReadOptions,
) -> Result<SessionInfo, SessionError> {
    let mut scan = Scanner::new(path, input, None, false);
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
            Err(e) if !options.recover && has_footer => return Err(e.into_session_error(path)),
            Err(StreamError::Io(source)) if !options.recover => {
                return Err(SessionError::Read { path: path.to_path_buf(), source });
            }
            Err(StreamError::Corrupt { .. }) if !options.recover => {
                return Err(SessionError::Truncated {
                    path: path.to_path_buf(),
                    readable_messages: scan.messages,
                    complete_chunks: scan.complete_chunks(),
                    readable_until: scan.last_log_time,
                });
            }
            Err(_) => {
                truncated = true;
                break;
            }
        }
    }
    let channels: Vec<ChannelDesc> = scan.channels.values().map(|c| c.as_ref().clone()).collect();
    let parts = Parts { channels, tallies, metadata, attachments, chunk_count: scan.complete_chunks() };
    Ok(parts.assemble(path, size, truncated))
}

#[cfg(test)]
mod tests;
