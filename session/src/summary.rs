//! What a session file holds, from its summary section when it has one, else
//! from a scan of the whole file.

mod indexed;
mod info;

use std::collections::{BTreeMap, HashMap};
use std::io::{Read, Seek, SeekFrom};
use std::path::Path;

use super::error::{SessionError, error_chain};
use super::metadata::{OUTCOME_METADATA, SESSION_METADATA, SessionMetadata, SessionOutcome};
use super::reader::ReadOptions;
use super::records::StreamError;
use super::scan::{Event, Scanner, check_session, footer_summary_start, open_session};
use super::stored::ChannelDesc;
pub use info::{ChannelSummary, SessionInfo};
use info::{ChannelTally, Parts};

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
