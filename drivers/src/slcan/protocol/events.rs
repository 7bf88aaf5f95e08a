//! What the decoder finds in an adapter's stream, and what it counts.

use thiserror::Error;

use super::wire::MAX_LINE;
use crate::can::protocol::CanFrame;

/// Why a line is not SLCAN.
#[derive(Clone, Copy, Debug, Error, PartialEq, Eq)]
pub enum MalformedReason {
    /// The first character names no line the adapter sends.
    #[error("unknown line type")]
    UnknownType,
    /// A CAN FD frame (`d`, `D`, `b`, `B` of CANable 2.0 firmware).
    #[error("CAN FD frames are not supported")]
    CanFd,
    /// The identifier is not 3 (or 8) hex digits.
    #[error("the identifier is not hex")]
    BadId,
    /// The identifier is beyond 0x7FF (11-bit) or 0x1FFFFFFF (29-bit).
    #[error("the identifier is out of range")]
    IdOutOfRange,
    /// The length is not a digit 0 to 8.
    #[error("the length is not 0-8")]
    BadLength,
    /// The line is not as long as its length says (with or without a
    /// 4-digit timestamp).
    #[error("the line's size does not match its length")]
    WrongSize,
    /// The data or the timestamp is not hex.
    #[error("the data or timestamp is not hex")]
    BadHex,
    /// More than [`MAX_LINE`] bytes without a terminator.
    #[error("longer than {MAX_LINE} bytes")]
    Overlong,
    /// A BEL arrived in the middle of the line.
    #[error("cut short by a BEL")]
    CutByBell,
}

/// What the decoder found in the adapter's stream.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum SlcanEvent {
    /// A frame the adapter received from the bus. For a remote frame
    /// `frame.data()` is as many zero bytes as the requested length.
    Frame {
        /// The frame.
        frame: CanFrame,
        /// A remote (RTR) frame: it carries a length but no data.
        remote: bool,
        /// The adapter's timestamp, milliseconds modulo 60000, when on (`Z1`).
        timestamp_ms: Option<u16>,
    },
    /// A lone `\r`: the last command succeeded.
    Ok,
    /// A BEL: the last command failed.
    Error,
    /// `z` / `Z`: a transmitted frame was queued (Lawicel adapters; others
    /// answer a transmission with [`SlcanEvent::Ok`]).
    TransmitAck {
        /// `Z`: the frame had a 29-bit identifier.
        extended: bool,
    },
    /// Another reply: `V..` / `v..` (version), `N..` (serial number), `F..`
    /// (status flags).
    Reply {
        /// The line, without its `\r`, non-printable bytes escaped.
        line: String,
    },
    /// A line that is none of the above; it is dropped.
    Malformed {
        /// Its first 40 bytes, non-printable bytes escaped.
        line: String,
        /// What is wrong with it.
        reason: MalformedReason,
    },
}

/// What the decoder counted so far.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SlcanCounters {
    /// Frames decoded (data and remote).
    pub frames: u64,
    /// Of which remote frames.
    pub remote_frames: u64,
    /// OK replies (lone `\r`).
    pub oks: u64,
    /// Error replies (BEL).
    pub errors: u64,
    /// Transmit acknowledgements (`z`, `Z`).
    pub transmit_acks: u64,
    /// Other replies (version, serial number, status flags).
    pub replies: u64,
    /// Lines dropped as malformed (overlong ones included).
    pub malformed: u64,
    /// Of which lines longer than [`MAX_LINE`].
    pub overlong: u64,
    /// Bytes of the dropped lines (terminators excluded).
    pub bytes_skipped: u64,
}

impl std::fmt::Display for SlcanCounters {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} frames ({} remote), {} OK, {} BEL, {} transmit acks, {} other replies, {} malformed lines \
             ({} overlong, {} bytes skipped)",
            self.frames,
            self.remote_frames,
            self.oks,
            self.errors,
            self.transmit_acks,
            self.replies,
            self.malformed,
            self.overlong,
            self.bytes_skipped
        )
    }
}
