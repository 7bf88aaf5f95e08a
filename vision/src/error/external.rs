//! [`ExternalError`]: what the external measurement source refuses (kept
//! here, below `sources`, so that [`super::VisionError`] can wrap it).

use thiserror::Error;

/// Why a message, a connection or the socket failed.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum ExternalError {
    /// The address could not be listened on.
    #[error("cannot listen on {addr}: {source}")]
    Listen {
        /// The address.
        addr: String,
        /// The cause.
        source: std::io::Error,
    },
    /// A line is not a message of the protocol.
    #[error("message {line}: {detail}")]
    BadMessage {
        /// Line number on the connection (1-based).
        line: u64,
        /// What is wrong (the JSON decoder's words).
        detail: String,
    },
    /// The first message is not a hello of this protocol and version.
    #[error("handshake: {detail}")]
    BadHandshake {
        /// What is wrong.
        detail: String,
    },
    /// A line longer than 32 MiB (`protocol::MAX_LINE_BYTES`).
    #[error("message {line} is longer than {limit} bytes; connection closed")]
    LineTooLong {
        /// Line number.
        line: u64,
        /// The limit (bytes).
        limit: usize,
    },
    /// The connection closed in the middle of a message.
    #[error("connection closed inside a message ({bytes} bytes without a newline)")]
    Truncated {
        /// Bytes of the unfinished message.
        bytes: usize,
    },
    /// A result's mask is unusable.
    #[error("result for frame {frame_t_ns} ns: mask {detail}")]
    BadMask {
        /// The frame.
        frame_t_ns: u64,
        /// What is wrong.
        detail: String,
    },
    /// A result's pose is unusable.
    #[error("result for frame {frame_t_ns} ns: pose {detail}")]
    BadPose {
        /// The frame.
        frame_t_ns: u64,
        /// What is wrong.
        detail: String,
    },
    /// A result for a frame time the server never announced.
    #[error("result for frame {frame_t_ns} ns: no such frame was sent")]
    UnknownFrame {
        /// The frame.
        frame_t_ns: u64,
    },
    /// A result older than the tracker accepts.
    #[error("result for frame {frame_t_ns} ns arrived {age_ns} ns after it, more than {max_age_ns} ns")]
    Late {
        /// The frame.
        frame_t_ns: u64,
        /// Time from the frame to the frame it arrived by (ns).
        age_ns: u64,
        /// The limit (ns).
        max_age_ns: u64,
    },
}

impl ExternalError {
    /// The short name sent to the client in `error` messages.
    pub fn kind(&self) -> &'static str {
        match self {
            ExternalError::Listen { .. } => "listen",
            ExternalError::BadMessage { .. } => "bad_message",
            ExternalError::BadHandshake { .. } => "bad_handshake",
            ExternalError::LineTooLong { .. } => "line_too_long",
            ExternalError::Truncated { .. } => "truncated",
            ExternalError::BadMask { .. } => "bad_mask",
            ExternalError::BadPose { .. } => "bad_pose",
            ExternalError::UnknownFrame { .. } => "unknown_frame",
            ExternalError::Late { .. } => "late",
        }
    }
}
