//! The one error type of the session module.

use std::io;
use std::path::PathBuf;

use slidetrack_core::TimeNs;
use thiserror::Error;

/// A failure to write, read or export a session file. Every variant names the
/// file it is about.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum SessionError {
    /// The session file could not be created (missing or unwritable directory,
    /// disk full, ...).
    #[error("cannot create session file {path}: {source}")]
    Create {
        /// The file that was to be created.
        path: PathBuf,
        /// What the operating system said.
        source: io::Error,
    },
    /// Writing to the session file failed. The recorder stops writing at the
    /// first failure; every later call reports this error again.
    #[error("writing session file {path} failed: {detail}")]
    Write {
        /// The file being written.
        path: PathBuf,
        /// The I/O error kind, when the failure came from the operating system.
        kind: Option<io::ErrorKind>,
        /// What went wrong.
        detail: String,
    },
    /// The recorder's writer thread is gone (it panicked, or `finish` already ran).
    #[error("the recorder for {path} has stopped: {detail}")]
    Closed {
        /// The file the recorder was writing.
        path: PathBuf,
        /// Why it stopped.
        detail: String,
    },
    /// A channel was registered twice with different content, or too many
    /// channels were registered.
    #[error("{path}: cannot register channel {topic}: {detail}")]
    Channel {
        /// The file being written.
        path: PathBuf,
        /// The topic being registered.
        topic: String,
        /// Why it was refused.
        detail: String,
    },
    /// A message could not be serialized to JSON.
    #[error("{path}: cannot serialize a message for {topic}: {source}")]
    Encode {
        /// The file being written.
        path: PathBuf,
        /// The channel's topic.
        topic: String,
        /// The serializer's error.
        source: serde_json::Error,
    },
    /// The file does not exist.
    #[error("session file {path} does not exist")]
    NotFound {
        /// The missing file.
        path: PathBuf,
    },
    /// The file exists but could not be opened or read.
    #[error("cannot read session file {path}: {source}")]
    Read {
        /// The file being read.
        path: PathBuf,
        /// What the operating system said.
        source: io::Error,
    },
    /// The file has no bytes at all.
    #[error("{path} is empty (0 bytes), not an MCAP session")]
    Empty {
        /// The empty file.
        path: PathBuf,
    },
    /// The file does not start with the MCAP magic bytes.
    #[error("{path} is not an MCAP file (it does not start with the MCAP magic bytes)")]
    NotMcap {
        /// The file being read.
        path: PathBuf,
    },
    /// The file ends before its summary and footer: its writer was killed or
    /// crashed. Reading with `recover` returns the complete chunks.
    #[error(
        "{path} is truncated (its writer stopped before finishing it): {readable_messages} \
         messages in {complete_chunks} complete chunks are readable; read them with --recover"
    )]
    Truncated {
        /// The truncated file.
        path: PathBuf,
        /// Messages readable up to the last complete chunk.
        readable_messages: u64,
        /// Chunks that are complete and valid.
        complete_chunks: u64,
        /// Log time of the last readable message, if any.
        readable_until: Option<TimeNs>,
    },
    /// The file is an MCAP file, but a record in it is malformed.
    #[error("{path} is corrupt (after reading {bytes_read} bytes): {detail}")]
    Corrupt {
        /// The file being read.
        path: PathBuf,
        /// How many bytes of the file had been read when the problem showed.
        bytes_read: u64,
        /// What is wrong, as the MCAP reader reports it.
        detail: String,
    },
    /// A message's payload does not decode as the expected type.
    #[error("{path}: message on {topic} at {log_time} does not decode: {source}")]
    Decode {
        /// The file being read.
        path: PathBuf,
        /// The message's topic.
        topic: String,
        /// The message's log time.
        log_time: TimeNs,
        /// The decoder's error.
        source: serde_json::Error,
    },
    /// The requested topic has no channel in the file.
    #[error("{path} has no channel {topic} (it has: {available})")]
    NoSuchTopic {
        /// The file being read.
        path: PathBuf,
        /// The topic asked for.
        topic: String,
        /// The topics the file has, comma-separated.
        available: String,
    },
    /// The channel cannot be flattened into CSV columns (an image channel, or
    /// not JSON-encoded).
    #[error("{path}: channel {topic} cannot be exported to CSV: {reason}")]
    NotTabular {
        /// The file being read.
        path: PathBuf,
        /// The channel's topic.
        topic: String,
        /// Why not.
        reason: String,
    },
    /// Writing an export (CSV) to its destination failed.
    #[error("writing the export of {path} failed: {source}")]
    Output {
        /// The session file being exported.
        path: PathBuf,
        /// What the destination said.
        source: io::Error,
    },
}

impl SessionError {
    /// Maps an error of opening a file for reading onto `NotFound` or `Read`.
    pub(crate) fn open(path: &std::path::Path, source: io::Error) -> SessionError {
        if source.kind() == io::ErrorKind::NotFound {
            SessionError::NotFound { path: path.to_path_buf() }
        } else {
            SessionError::Read { path: path.to_path_buf(), source }
        }
    }
}
