//! Reading messages back, in file order, with bounded memory.

use std::collections::HashSet;
use std::fs::File;
use std::io::{Read, Seek};
use std::path::{Path, PathBuf};

use serde::de::DeserializeOwned;
use slidetrack_core::TimeNs;

use super::channel::ChannelMessage;
use super::error::{SessionError, error_chain};
use super::scan::{Event, Scanner, check_session, footer_summary_start, open_session, truncated_error};
use super::stored::{ChannelDesc, RawMessage};

/// How to read a session file.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ReadOptions {
    /// Read a file whose writer died (no summary, no footer) up to its last
    /// complete chunk, and stop quietly at a corrupt record. Without it such
    /// files fail with [`SessionError::Truncated`] or [`SessionError::Corrupt`].
    pub recover: bool,
}

impl ReadOptions {
    /// Options that recover truncated files.
    pub fn recover() -> ReadOptions {
        ReadOptions { recover: true }
    }
}

/// Iterates over the messages of a session file in file order (log-time
/// order for files written by [`super::Recorder`]), holding one chunk at a time.
///
/// [`MessageReader::open`] reads a file; [`MessageReader::from_reader`] reads
/// any seekable input (a session in memory).
///
/// # Contract
/// - `open` fails when the file is missing, empty, not MCAP, or (without
///   `recover`) truncated; the truncated error counts the readable messages.
/// - Without `recover`, a corrupt record yields one `Err` and ends the
///   iteration. With `recover`, reading stops quietly at the first corrupt or
///   incomplete chunk and [`MessageReader::truncated`] turns true.
pub struct MessageReader<R = File> {
    scan: Scanner<R>,
    recover: bool,
    truncated: bool,
}

impl MessageReader {
    /// Opens `path`, yielding only messages on `topics` (every topic when empty).
    pub fn open(path: impl AsRef<Path>, topics: &[&str], options: ReadOptions) -> Result<Self, SessionError> {
        let path = path.as_ref();
        let (file, size) = open_session(path)?;
        MessageReader::start(path, file, size, topics, options)
    }
}

impl<R: Read + Seek> MessageReader<R> {
    /// Reads the session held by `input` (from its start, for example a
    /// `Cursor` over the bytes of a file), yielding only messages on `topics`
    /// (every topic when empty). `name` stands for the file in errors and
    /// [`MessageReader::path`]. Fails as [`MessageReader::open`] does.
    pub fn from_reader(
        name: impl AsRef<Path>,
        mut input: R,
        topics: &[&str],
        options: ReadOptions,
    ) -> Result<Self, SessionError> {
        let name = name.as_ref();
        let size = check_session(name, &mut input)?;
        MessageReader::start(name, input, size, topics, options)
    }

    fn start(
        path: &Path,
        mut input: R,
        size: u64,
        topics: &[&str],
        options: ReadOptions,
    ) -> Result<Self, SessionError> {
        let read_err = |source| SessionError::Read { path: path.to_path_buf(), source };
        let complete = footer_summary_start(&mut input, size).map_err(read_err)?.is_some();
        if !complete && !options.recover {
            return Err(truncated_error(path, input));
        }
        let topics: Option<HashSet<String>> =
            (!topics.is_empty()).then(|| topics.iter().map(|t| t.to_string()).collect());
        Ok(MessageReader {
            scan: Scanner::new(path, input, topics, true),
            recover: options.recover,
            truncated: false,
        })
    }
}

impl<R> MessageReader<R> {
    /// True once reading stopped early at an incomplete or corrupt chunk
    /// (only with `recover`).
    pub fn truncated(&self) -> bool {
        self.truncated
    }

    /// The channels declared so far (all of them once the iteration is over).
    pub fn channels(&self) -> impl Iterator<Item = &ChannelDesc> {
        self.scan.channels.values().map(|c| c.as_ref())
    }

    /// The file being read.
    pub fn path(&self) -> &Path {
        &self.scan.path
    }
}

impl<R: Read> Iterator for MessageReader<R> {
    type Item = Result<RawMessage, SessionError>;

    fn next(&mut self) -> Option<Self::Item> {
        loop {
            match self.scan.next_event() {
                Ok(Some(Event::Message(m))) => return Some(Ok(m)),
                Ok(Some(_)) => {}
                Ok(None) => return None,
                Err(e) if self.recover => {
                    let e = e.into_session_error(&self.scan.path);
                    tracing::debug!("reading stopped: {}", error_chain(&e));
                    self.truncated = true;
                    return None;
                }
                Err(e) => return Some(Err(e.into_session_error(&self.scan.path))),
            }
        }
    }
}

/// Every message on `topic`, decoded from JSON, with its log time.
pub fn read_json<T: DeserializeOwned>(
    path: impl AsRef<Path>,
    topic: &str,
    options: ReadOptions,
) -> Result<Vec<(TimeNs, T)>, SessionError> {
    let path = path.as_ref();
    let mut reader = MessageReader::open(path, &[topic], options)?;
    let mut out = Vec::new();
    for message in reader.by_ref() {
        let m = message?;
        let value = serde_json::from_slice(&m.data).map_err(|source| SessionError::Decode {
            path: path.to_path_buf(),
            topic: topic.to_string(),
            log_time: m.log_time,
            source,
        })?;
        out.push((m.log_time, value));
    }
    if out.is_empty() && !reader.channels().any(|c| c.topic == topic) {
        return Err(no_such_topic(path.to_path_buf(), topic, reader.channels()));
    }
    Ok(out)
}

/// Every message of `T`'s channel, with its log time.
pub fn read_channel<T: ChannelMessage>(
    path: impl AsRef<Path>,
    options: ReadOptions,
) -> Result<Vec<(TimeNs, T)>, SessionError> {
    read_json(path, T::TOPIC, options)
}

pub(crate) fn no_such_topic<'a>(
    path: PathBuf,
    topic: &str,
    channels: impl Iterator<Item = &'a ChannelDesc>,
) -> SessionError {
    let mut topics: Vec<&str> = channels.map(|c| c.topic.as_str()).collect();
    topics.sort_unstable();
    topics.dedup();
    let available = if topics.is_empty() { "no channels".to_string() } else { topics.join(", ") };
    SessionError::NoSuchTopic { path, topic: topic.to_string(), available }
}

/// The session time at which the sliding cycles ended: the first release or
/// abort of `/protocol/events`; `None` when the trial never got there (or the
/// session has no protocol events).
pub fn release_time(path: impl AsRef<Path>, options: ReadOptions) -> Result<Option<TimeNs>, SessionError> {
    use super::messages::ProtocolEvent;
    match read_channel::<ProtocolEvent>(path, options) {
        Ok(events) => Ok(events.iter().find(|(_, e)| e.ends_cycles()).map(|(t, _)| *t)),
        Err(SessionError::NoSuchTopic { .. }) => Ok(None),
        Err(e) => Err(e),
    }
}
