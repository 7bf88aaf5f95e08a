//! The streaming decoder of what an adapter sends.

use super::events::{MalformedReason, SlcanCounters, SlcanEvent};
use super::wire::{BEL, CR, MAX_LINE};
use crate::can::protocol::CanFrame;

/// Characters of a malformed line kept in [`SlcanEvent::Malformed`].
const SHOWN: usize = 40;

/// Splits an adapter's byte stream into lines and decodes them.
///
/// # Contract
/// - Takes bytes cut anywhere ([`feed`](Self::feed)); calls back with the
///   events in stream order. No input panics.
/// - A line ends at `\r` or BEL. A lone `\r` is [`SlcanEvent::Ok`]; every
///   BEL is [`SlcanEvent::Error`], and bytes before a BEL that no `\r`
///   ended are a cut line ([`MalformedReason::CutByBell`]) reported first.
///   Line feeds at the start of a line are ignored (for adapters that end
///   lines with `\r\n`).
/// - A line that is not SLCAN is reported as [`SlcanEvent::Malformed`] and
///   dropped; the next line decodes normally.
/// - At most [`MAX_LINE`] bytes are held: a longer line is reported
///   ([`MalformedReason::Overlong`]) as soon as it overflows, and its bytes
///   are skipped up to the next terminator.
#[derive(Debug)]
pub struct SlcanDecoder {
    line: Vec<u8>,
    overlong: bool,
    counters: SlcanCounters,
}

impl Default for SlcanDecoder {
    fn default() -> Self {
        SlcanDecoder::new()
    }
}

impl SlcanDecoder {
    /// A decoder at the start of a stream.
    pub fn new() -> SlcanDecoder {
        SlcanDecoder {
            line: Vec::with_capacity(MAX_LINE),
            overlong: false,
            counters: SlcanCounters::default(),
        }
    }

    /// Decodes `bytes`, calling `on_event` for every event they complete.
    pub fn feed(&mut self, bytes: &[u8], mut on_event: impl FnMut(SlcanEvent)) {
        let mut rest = bytes;
        while let Some(end) = rest.iter().position(|&b| b == CR || b == BEL) {
            self.take(&rest[..end], &mut on_event);
            self.end_line(rest[end], &mut on_event);
            rest = &rest[end + 1..];
        }
        self.take(rest, &mut on_event);
    }

    /// The counters so far.
    pub fn counters(&self) -> SlcanCounters {
        self.counters
    }

    /// Bytes held of a line not ended yet (at most [`MAX_LINE`]).
    pub fn buffered(&self) -> usize {
        self.line.len()
    }

    /// Forgets the line begun, for example after the port's input was flushed.
    pub fn clear_line(&mut self) {
        self.line.clear();
        self.overlong = false;
    }

    /// Appends bytes of the current line (no terminator among them).
    fn take(&mut self, mut bytes: &[u8], on_event: &mut impl FnMut(SlcanEvent)) {
        if self.overlong {
            self.counters.bytes_skipped += bytes.len() as u64;
            return;
        }
        if self.line.is_empty() {
            while let [b'\n', tail @ ..] = bytes {
                bytes = tail;
            }
        }
        let room = MAX_LINE - self.line.len();
        if bytes.len() <= room {
            self.line.extend_from_slice(bytes);
            return;
        }
        self.line.extend_from_slice(&bytes[..room]);
        self.counters.malformed += 1;
        self.counters.overlong += 1;
        self.counters.bytes_skipped += (MAX_LINE + bytes.len() - room) as u64;
        on_event(SlcanEvent::Malformed { line: shown(&self.line, SHOWN), reason: MalformedReason::Overlong });
        self.line.clear();
        self.overlong = true;
    }

    fn end_line(&mut self, terminator: u8, on_event: &mut impl FnMut(SlcanEvent)) {
        let bell = terminator == BEL;
        if self.overlong {
            self.overlong = false;
        } else if !self.line.is_empty() {
            let event = if bell { self.malformed(MalformedReason::CutByBell) } else { self.decode_line() };
            self.line.clear();
            on_event(event);
        } else if !bell {
            self.counters.oks += 1;
            on_event(SlcanEvent::Ok);
        }
        if bell {
            self.counters.errors += 1;
            on_event(SlcanEvent::Error);
        }
    }

    fn malformed(&mut self, reason: MalformedReason) -> SlcanEvent {
        self.counters.malformed += 1;
        self.counters.bytes_skipped += self.line.len() as u64;
        SlcanEvent::Malformed { line: shown(&self.line, SHOWN), reason }
    }

    /// Decodes the (non-empty) line held.
    fn decode_line(&mut self) -> SlcanEvent {
        let line = &self.line[..];
        let decoded = match line[0] {
            b't' | b'T' | b'r' | b'R' => parse_frame_line(line)
                .map(|(frame, remote, timestamp_ms)| SlcanEvent::Frame { frame, remote, timestamp_ms }),
            b'z' | b'Z' if line.len() == 1 => Ok(SlcanEvent::TransmitAck { extended: line[0] == b'Z' }),
            b'V' | b'v' | b'N' | b'F' => Ok(SlcanEvent::Reply { line: shown(line, MAX_LINE) }),
            b'd' | b'D' | b'b' | b'B' => Err(MalformedReason::CanFd),
            _ => Err(MalformedReason::UnknownType),
        };
        let c = &mut self.counters;
        match &decoded {
            Ok(SlcanEvent::Frame { remote, .. }) => {
                c.frames += 1;
                c.remote_frames += u64::from(*remote);
            }
            Ok(SlcanEvent::TransmitAck { .. }) => c.transmit_acks += 1,
            Ok(_) => c.replies += 1,
            Err(_) => {}
        }
        decoded.unwrap_or_else(|reason| self.malformed(reason))
    }
}

/// The value of up to 8 hex digits (either case); `None` for anything else.
fn hex_value(digits: &[u8]) -> Option<u32> {
    if digits.is_empty() || digits.len() > 8 {
        return None;
    }
    digits.iter().try_fold(0u32, |acc, &d| Some((acc << 4) | char::from(d).to_digit(16)?))
}

/// Parses one frame line without its `\r` (`t7108001234567890ABC00`, with or
/// without a 4-digit timestamp): the frame, whether it is a remote frame
/// (its data then being as many zero bytes as its length), the timestamp.
pub fn parse_frame_line(line: &[u8]) -> Result<(CanFrame, bool, Option<u16>), MalformedReason> {
    let (extended, remote) = match line.first() {
        Some(b't') => (false, false),
        Some(b'T') => (true, false),
        Some(b'r') => (false, true),
        Some(b'R') => (true, true),
        _ => return Err(MalformedReason::UnknownType),
    };
    let id_len = if extended { 8 } else { 3 };
    let (id, rest) = line[1..].split_at_checked(id_len).ok_or(MalformedReason::WrongSize)?;
    let id = hex_value(id).ok_or(MalformedReason::BadId)?;
    let (&len, rest) = rest.split_first().ok_or(MalformedReason::WrongSize)?;
    let len = match len {
        b'0'..=b'8' => usize::from(len - b'0'),
        _ => return Err(MalformedReason::BadLength),
    };
    let data_chars = if remote { 0 } else { 2 * len };
    let timestamp_ms = match rest.len().checked_sub(data_chars) {
        Some(0) => None,
        Some(4) => Some(hex_value(&rest[data_chars..]).ok_or(MalformedReason::BadHex)? as u16),
        _ => return Err(MalformedReason::WrongSize),
    };
    let mut data = [0u8; 8];
    if !remote {
        for (byte, pair) in data.iter_mut().zip(rest[..data_chars].chunks_exact(2)) {
            *byte = hex_value(pair).ok_or(MalformedReason::BadHex)? as u8;
        }
    }
    let frame = CanFrame::new(id, extended, &data[..len]).ok_or(MalformedReason::IdOutOfRange)?;
    Ok((frame, remote, timestamp_ms))
}

/// `bytes` as printable text (at most `max` bytes of it, `…` when cut).
fn shown(bytes: &[u8], max: usize) -> String {
    let mut s = bytes[..bytes.len().min(max)].escape_ascii().to_string();
    if bytes.len() > max {
        s.push('…');
    }
    s
}
