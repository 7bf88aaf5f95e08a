//! Opening a session, and a linear scan of its messages, metadata and
//! attachments on top of the [record stream](super::records): a chunk's
//! messages are handed out only once the whole chunk has been read,
//! decompressed and its CRC checked, so a file cut short yields exactly its
//! complete chunks.

use std::collections::{BTreeMap, HashMap, HashSet};
use std::fs::File;
use std::io::{self, Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};
use std::sync::Arc;

use mcap::records::op;
use slidetrack_core::TimeNs;

use super::error::SessionError;
use super::records::{Payloads, Record, RecordStream, StreamError, read_full};
use super::stored::{AttachmentSummary, ChannelDesc, RawMessage};

/// Footer record (1 + 8 + 20 bytes) and end magic (8 bytes).
pub(crate) const FOOTER_AND_MAGIC: u64 = 37;

/// Opens a session file, checking that it is an MCAP file. Returns the file
/// (positioned at 0) and its size.
pub(crate) fn open_session(path: &Path) -> Result<(File, u64), SessionError> {
    let mut file = File::open(path).map_err(|e| SessionError::open(path, e))?;
    let meta = file.metadata().map_err(|source| SessionError::Read { path: path.to_path_buf(), source })?;
    if meta.is_dir() {
        let source = io::Error::new(io::ErrorKind::IsADirectory, "is a directory");
        return Err(SessionError::Read { path: path.to_path_buf(), source });
    }
    let size = check_session(path, &mut file)?;
    Ok((file, size))
}

/// Checks that `input` holds an MCAP file (`path` names it in errors).
/// Returns its size, with `input` positioned at 0.
pub(crate) fn check_session(path: &Path, input: &mut (impl Read + Seek)) -> Result<u64, SessionError> {
    let read_err = |source| SessionError::Read { path: path.to_path_buf(), source };
    let size = input.seek(SeekFrom::End(0)).map_err(read_err)?;
    if size == 0 {
        return Err(SessionError::Empty { path: path.to_path_buf() });
    }
    input.seek(SeekFrom::Start(0)).map_err(read_err)?;
    let mut magic = [0u8; 8];
    let got = read_full(input, &mut magic).map_err(read_err)?;
    if got < magic.len() || magic != mcap::MAGIC {
        return Err(SessionError::NotMcap { path: path.to_path_buf() });
    }
    input.seek(SeekFrom::Start(0)).map_err(read_err)?;
    Ok(size)
}

/// The footer's `summary_start`, or `None` when the file does not end with a
/// footer and the end magic (its writer did not finish).
pub(crate) fn footer_summary_start(input: &mut (impl Read + Seek), size: u64) -> io::Result<Option<u64>> {
    if size < 8 + FOOTER_AND_MAGIC {
        return Ok(None);
    }
    let mut tail = [0u8; FOOTER_AND_MAGIC as usize];
    input.seek(SeekFrom::Start(size - FOOTER_AND_MAGIC))?;
    let got = read_full(input, &mut tail)?;
    input.seek(SeekFrom::Start(0))?;
    let (record, magic) = tail.split_at(29);
    let len = u64::from_le_bytes(record[1..9].try_into().unwrap_or_default());
    if got < tail.len() || record[0] != op::FOOTER || len != 20 || magic != mcap::MAGIC {
        return Ok(None);
    }
    Ok(Some(u64::from_le_bytes(record[9..17].try_into().unwrap_or_default())))
}

/// What a scan yields besides messages.
pub(crate) enum Event {
    Message(RawMessage),
    Metadata { name: String, map: BTreeMap<String, String> },
    Attachment(AttachmentSummary),
}

/// A streaming reader of one session file's messages, metadata and
/// attachments, which keeps track of its schemas and channels.
pub(crate) struct Scanner<R> {
    pub(crate) path: PathBuf,
    stream: RecordStream<R>,
    schemas: HashMap<u16, (String, String)>,
    pub(crate) channels: BTreeMap<u16, Arc<ChannelDesc>>,
    topics: Option<HashSet<String>>,
    /// Messages read so far (on every topic), all in complete chunks.
    pub(crate) messages: u64,
    /// The latest log time among those messages.
    pub(crate) last_log_time: Option<TimeNs>,
}

impl<R: Read> Scanner<R> {
    /// A scanner of `input` (the whole file from its start). Only messages on
    /// `topics` (all when `None`) are yielded, without payload unless `keep_data`.
    pub(crate) fn new(path: &Path, input: R, topics: Option<HashSet<String>>, keep_data: bool) -> Self {
        let payloads = match &topics {
            _ if !keep_data => Payloads::None,
            None => Payloads::All,
            Some(topics) => Payloads::Topics(topics.clone()),
        };
        Scanner {
            path: path.to_path_buf(),
            stream: RecordStream::new(input, payloads),
            schemas: HashMap::new(),
            channels: BTreeMap::new(),
            topics,
            messages: 0,
            last_log_time: None,
        }
    }

    /// Chunks read completely and verified so far.
    pub(crate) fn complete_chunks(&self) -> u64 {
        self.stream.complete_chunks()
    }

    /// The next event; `Ok(None)` at the end of a complete file. After an
    /// error the scan is over and later calls return `Ok(None)`.
    pub(crate) fn next_event(&mut self) -> Result<Option<Event>, StreamError> {
        while let Some(record) = self.stream.next_record()? {
            match record {
                Record::Schema { id, name, encoding, .. } => {
                    self.schemas.insert(id, (name, encoding));
                }
                Record::Channel(c) => {
                    let (schema_name, schema_encoding) =
                        self.schemas.get(&c.schema_id).cloned().unwrap_or_default();
                    let desc = ChannelDesc {
                        id: c.id,
                        topic: c.topic,
                        schema_name,
                        schema_encoding,
                        message_encoding: c.message_encoding,
                        metadata: c.metadata,
                    };
                    self.channels.insert(c.id, Arc::new(desc));
                }
                Record::Message { header, data } => {
                    // The stream checked that the channel was declared.
                    let Some(channel) = self.channels.get(&header.channel_id) else { continue };
                    let log_time = TimeNs(header.log_time);
                    self.messages += 1;
                    self.last_log_time = self.last_log_time.max(Some(log_time));
                    if self.topics.as_ref().is_none_or(|t| t.contains(&channel.topic)) {
                        return Ok(Some(Event::Message(RawMessage {
                            channel: Arc::clone(channel),
                            log_time,
                            publish_time: TimeNs(header.publish_time),
                            sequence: header.sequence,
                            data,
                        })));
                    }
                }
                Record::Metadata(m) => return Ok(Some(Event::Metadata { name: m.name, map: m.metadata })),
                Record::Attachment(a) => {
                    let size_bytes = a.data.len() as u64;
                    let (name, media_type) = (a.name, a.media_type);
                    return Ok(Some(Event::Attachment(AttachmentSummary { name, media_type, size_bytes })));
                }
                Record::Header(_) | Record::DataEnd => {}
            }
        }
        Ok(None)
    }
}

/// The error of a file that ends before its footer, after counting what is readable.
pub(crate) fn truncated_error<R: Read>(path: &Path, input: R) -> SessionError {
    let mut scan = Scanner::new(path, input, Some(HashSet::new()), false);
    while let Ok(Some(_)) = scan.next_event() {}
    SessionError::Truncated {
        path: path.to_path_buf(),
        readable_messages: scan.messages,
        complete_chunks: scan.complete_chunks(),
        readable_until: scan.last_log_time,
    }
}
