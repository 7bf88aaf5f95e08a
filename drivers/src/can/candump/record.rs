//! The records of a candump log and the parse error, shared by both line
//! formats ([`super::parse_line`] and [`super::plain`]).

use thiserror::Error;

/// One record of a candump log.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct CandumpRecord {
    /// Reception time in microseconds: since the Unix epoch (host clock)
    /// for `candump -l` and `-t a`; since the first frame (`-t z`) or the
    /// previous one (`-t d`) for those; `None` when the line has none.
    pub t_us: Option<u64>,
    /// The interface it was received on (`can0`).
    pub interface: String,
    /// What the frame is.
    pub frame: CandumpFrame,
}

/// The frame of a [`CandumpRecord`].
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum CandumpFrame {
    /// A classic data frame.
    Data {
        /// The identifier (11 or 29 bits).
        id: u32,
        /// True for a 29-bit identifier.
        extended: bool,
        /// 0 to 8 bytes.
        data: Vec<u8>,
    },
    /// A remote (RTR) frame, an error frame or a CAN FD frame: logged, not decoded here.
    Other,
}

/// A line that is not a candump record.
#[derive(Clone, Debug, Error, PartialEq, Eq)]
#[error("not a candump record: {reason}")]
pub struct CandumpParseError {
    /// What is wrong with the line.
    pub reason: &'static str,
}

/// Error flag of a can-utils frame id (`CAN_ERR_FLAG`).
pub(crate) const ERROR_FLAG: u32 = 0x2000_0000;

pub(crate) fn bad(reason: &'static str) -> CandumpParseError {
    CandumpParseError { reason }
}

/// Parses `(SECONDS.MICROS)` without its parentheses into microseconds.
pub(crate) fn parse_seconds(time: &str) -> Result<u64, CandumpParseError> {
    let (secs, micros) = time.split_once('.').ok_or_else(|| bad("time without a fraction"))?;
    let secs: u64 = secs.parse().map_err(|_| bad("bad seconds"))?;
    if micros.len() != 6 {
        return Err(bad("time fraction is not 6 digits"));
    }
    let micros: u64 = micros.parse().map_err(|_| bad("bad microseconds"))?;
    secs.checked_mul(1_000_000).and_then(|s| s.checked_add(micros)).ok_or_else(|| bad("time"))
}
