//! The error type of the session module, and the causes it wraps.
//!
//! Every message states what failed and on which file, without repeating the
//! cause: the cause is the error's [`source`](std::error::Error::source), so
//! printing the chain joined by `": "` gives one line such as
//! `cannot read session file x.mcap: Permission denied (os error 13)`.

use std::fmt;
use std::io;
use std::path::PathBuf;
use std::sync::Arc;

use mcap::McapError;
use slidetrack_core::TimeNs;
use thiserror::Error;

/// A failure to write, read or export a session file. Every variant names the
/// file it is about.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum SessionError {
    /// The session file could not be created (missing or unwritable directory,
    /// disk full, ...).
    #[error("cannot create session file {path}")]
    Create {
        /// The file that was to be created.
        path: PathBuf,
        /// What the operating system said.
        #[source]
        source: io::Error,
    },
    /// Writing to the session file failed. The recorder stops writing at the
    /// first failure; every later call reports this error again.
    #[error("writing session file {path} failed")]
    Write {
        /// The file being written.
        path: PathBuf,
        /// The I/O error kind, when the failure came from the operating system.
        kind: Option<io::ErrorKind>,
        /// What refused the write.
        #[source]
        source: WriteFailure,
    },
    /// A rewritten session could not take the place of the original, which
    /// is left as it was.
    #[error("cannot replace {path} by its rewritten copy: {step} failed")]
    Replace {
        /// The session file being rewritten.
        path: PathBuf,
        /// The step that failed.
        step: ReplaceStep,
        /// What the operating system said.
        #[source]
        source: io::Error,
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
    #[error("{path}: cannot serialize a message for {topic}")]
    Encode {
        /// The file being written.
        path: PathBuf,
        /// The channel's topic.
        topic: String,
        /// The serializer's error.
        #[source]
        source: serde_json::Error,
    },
    /// The file does not exist.
    #[error("session file {path} does not exist")]
    NotFound {
        /// The missing file.
        path: PathBuf,
    },
    /// The file exists but could not be opened or read.
    #[error("cannot read session file {path}")]
    Read {
        /// The file being read.
        path: PathBuf,
        /// What the operating system said.
        #[source]
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
    #[error("{path} is corrupt (after reading {bytes_read} bytes)")]
    Corrupt {
        /// The file being read.
        path: PathBuf,
        /// How many bytes of the file had been read when the problem showed.
        bytes_read: u64,
        /// What is wrong.
        #[source]
        source: Corruption,
    },
    /// A message's payload does not decode as the expected type.
    #[error("{path}: message on {topic} at {log_time} does not decode")]
    Decode {
        /// The file being read.
        path: PathBuf,
        /// The message's topic.
        topic: String,
        /// The message's log time.
        log_time: TimeNs,
        /// The decoder's error.
        #[source]
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
    #[error("writing the export of {path} failed")]
    Output {
        /// The session file being exported.
        path: PathBuf,
        /// What the destination said.
        #[source]
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

/// What refused a write of a session file. Cheap to clone: the recorder
/// reports its first failure again on every later call.
#[derive(Clone, Debug, Error)]
#[non_exhaustive]
pub enum WriteFailure {
    /// The operating system refused a write, flush or sync.
    #[error(transparent)]
    Io(Arc<io::Error>),
    /// The MCAP writer refused a record (too many schemas, a record too large, ...).
    #[error(transparent)]
    Mcap(Arc<McapError>),
    /// The recorder's statistics message could not be serialized.
    #[error(transparent)]
    Encode(Arc<serde_json::Error>),
}

impl WriteFailure {
    /// The I/O error kind, when the operating system refused the write.
    pub fn io_kind(&self) -> Option<io::ErrorKind> {
        match self {
            WriteFailure::Io(e) => Some(e.kind()),
            _ => None,
        }
    }
}

impl From<io::Error> for WriteFailure {
    fn from(e: io::Error) -> WriteFailure {
        WriteFailure::Io(Arc::new(e))
    }
}

impl From<McapError> for WriteFailure {
    /// An I/O error inside the MCAP writer is reported as the I/O error itself.
    fn from(e: McapError) -> WriteFailure {
        match e {
            McapError::Io(io) => WriteFailure::Io(Arc::new(io)),
            other => WriteFailure::Mcap(Arc::new(other)),
        }
    }
}

/// A step of replacing a session file by its rewritten copy.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum ReplaceStep {
    /// Making the rewritten copy durable (`fsync`).
    Sync,
    /// Reading the original's permissions.
    ReadPermissions,
    /// Giving the copy the original's permissions.
    SetPermissions,
    /// Renaming the copy over the original.
    Rename,
}

impl fmt::Display for ReplaceStep {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            ReplaceStep::Sync => "syncing the rewritten copy",
            ReplaceStep::ReadPermissions => "reading the original's permissions",
            ReplaceStep::SetPermissions => "setting the copy's permissions",
            ReplaceStep::Rename => "renaming the copy over the original",
        })
    }
}

/// What is wrong in a corrupt session file.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum Corruption {
    /// The MCAP reader refused the file's structure (a record length past the
    /// end, a data-section CRC mismatch, an unknown compression, ...).
    #[error("invalid MCAP data")]
    Mcap(#[source] McapError),
    /// A chunk does not decompress, or its CRC does not match.
    #[error("a chunk does not decode")]
    Chunk(#[source] McapError),
    /// A chunk's records end in the middle of a record.
    #[error("a chunk ends in the middle of a record")]
    ChunkEndsEarly,
    /// A record does not parse.
    #[error("record {opcode:#04x} does not parse")]
    Record {
        /// The record's opcode.
        opcode: u8,
        /// The parser's error.
        #[source]
        source: McapError,
    },
    /// An attachment record's lengths do not add up.
    #[error("malformed attachment record")]
    Attachment,
    /// A message names a channel that was never declared before it.
    #[error("message on undeclared channel id {channel_id}")]
    UndeclaredChannel {
        /// The channel id the message names.
        channel_id: u16,
    },
    /// The footer's summary offset lies past the footer.
    #[error("the summary section would start at byte {summary_start}, past the footer")]
    SummaryStart {
        /// The footer's `summary_start` (bytes from the start of the file).
        summary_start: u64,
    },
    /// The summary section is larger than a reader accepts.
    #[error("the summary section is too large ({length} bytes)")]
    SummaryTooLarge {
        /// Its length (bytes).
        length: u64,
    },
    /// The summary section holds a record that has no place there.
    #[error("the summary section holds a record {opcode:#04x}, which does not belong there")]
    SummaryRecord {
        /// The stray record's opcode.
        opcode: u8,
    },
    /// The summary section does not parse.
    #[error("the summary section does not parse")]
    Summary(#[source] McapError),
    /// An index in the summary points outside the file, or at something
    /// other than the record it indexes.
    #[error("a {index} index points at no valid record (offset {offset}, {length} bytes)")]
    Index {
        /// Which index: `message` or `metadata`.
        index: &'static str,
        /// Where it points (bytes from the start of the file).
        offset: u64,
        /// How long the indexed record should be (bytes).
        length: u64,
    },
}

/// `e` and its causes on one line, joined by `": "` (for logs).
pub(crate) fn error_chain(e: &dyn std::error::Error) -> String {
    let mut line = e.to_string();
    let mut cause = e.source();
    while let Some(c) = cause {
        line.push_str(": ");
        line.push_str(&c.to_string());
        cause = c.source();
    }
    line
}
