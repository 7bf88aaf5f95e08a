//! The uSkin-style serial stream (see `docs/protocols.md`): its frame format,
//! an encoder, and a decoder without I/O.
//!
//! One frame carries one scan of one sensor module:
//!
//! ```text
//! offset  size  field
//! 0       2     sync 0xA5 0x5A
//! 2       2     payload length L in bytes, u16 big-endian (6..=384, a multiple of 6)
//! 4       1     module id (the module's index on the board)
//! 5       2     scan sequence counter, u16 big-endian (shared by the modules of one scan, wraps)
//! 7       L     L/6 taxels, each x, y, z as u16 big-endian raw counts
//! 7+L     2     CRC-16/CCITT-FALSE of bytes 2..7+L, big-endian
//! ```
//!
//! [`SerialDecoder`] takes bytes as they come ([`SerialDecoder::push`]) and
//! yields [`SerialEvent`]s: frames, and the typed problems it met on the way
//! (CRC errors, resynchronisations, sequence gaps). It holds at most
//! [`DECODER_CAPACITY`] bytes whatever it is fed.

use crc::{CRC_16_IBM_3740, Crc, Table};
use slidetrack_core::{DecoderCounters, RawTaxel};
use thiserror::Error;

/// The two bytes that start every frame.
pub const SYNC: [u8; 2] = [0xA5, 0x5A];
/// Bytes before the payload: sync, length, module, sequence.
pub const HEADER_LEN: usize = 7;
/// Bytes of the CRC after the payload.
pub const CRC_LEN: usize = 2;
/// Bytes per taxel in the payload: x, y, z as u16.
pub const TAXEL_BYTES: usize = 6;
/// Most taxels one frame carries.
pub const MAX_TAXELS: usize = 64;
/// Length of the longest frame (bytes).
pub const MAX_FRAME_LEN: usize = HEADER_LEN + MAX_TAXELS * TAXEL_BYTES + CRC_LEN;
/// Bytes the decoder buffers at most.
pub const DECODER_CAPACITY: usize = 8 * MAX_FRAME_LEN;

/// CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF, not reflected), slice-by-16.
static CRC16: Crc<u16, Table<16>> = Crc::<u16, Table<16>>::new(&CRC_16_IBM_3740);

/// The CRC of the frame format over `bytes`.
pub fn crc16(bytes: &[u8]) -> u16 {
    CRC16.checksum(bytes)
}

/// Length in bytes of a frame carrying `taxels` taxels.
pub fn frame_len(taxels: usize) -> usize {
    HEADER_LEN + taxels * TAXEL_BYTES + CRC_LEN
}

/// A frame that cannot be encoded.
#[derive(Clone, Copy, Debug, Error, PartialEq, Eq)]
pub enum FrameEncodeError {
    /// A frame carries 1 to [`MAX_TAXELS`] taxels.
    #[error("a serial frame carries 1 to {MAX_TAXELS} taxels, not {taxels}")]
    TaxelCount {
        /// The number asked for.
        taxels: usize,
    },
}

/// One scan of one sensor module, as decoded from a frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ModuleFrame {
    /// The module's index on the board.
    pub module: u8,
    /// The board's scan counter (wraps at 65536).
    pub sequence: u16,
    count: u8,
    taxels: [RawTaxel; MAX_TAXELS],
}

impl ModuleFrame {
    /// A frame of `module` at `sequence` carrying `taxels` (raw counts `[x, y, z]`).
    pub fn new(module: u8, sequence: u16, taxels: &[RawTaxel]) -> Result<ModuleFrame, FrameEncodeError> {
        if taxels.is_empty() || taxels.len() > MAX_TAXELS {
            return Err(FrameEncodeError::TaxelCount { taxels: taxels.len() });
        }
        let mut all = [[0; 3]; MAX_TAXELS];
        all[..taxels.len()].copy_from_slice(taxels);
        Ok(ModuleFrame { module, sequence, count: taxels.len() as u8, taxels: all })
    }

    /// The taxels, `[x, y, z]` raw counts each.
    pub fn taxels(&self) -> &[RawTaxel] {
        &self.taxels[..usize::from(self.count)]
    }

    /// Appends the frame's bytes to `out`.
    pub fn encode_into(&self, out: &mut Vec<u8>) {
        let payload_len = self.taxels().len() * TAXEL_BYTES;
        let start = out.len();
        out.extend_from_slice(&SYNC);
        out.extend_from_slice(&(payload_len as u16).to_be_bytes());
        out.push(self.module);
        out.extend_from_slice(&self.sequence.to_be_bytes());
        for taxel in self.taxels() {
            for v in taxel {
                out.extend_from_slice(&v.to_be_bytes());
            }
        }
        let crc = crc16(&out[start + 2..]);
        out.extend_from_slice(&crc.to_be_bytes());
    }

    /// The frame's bytes.
    pub fn encode(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(frame_len(self.taxels().len()));
        self.encode_into(&mut out);
        out
    }

    fn parse(module: u8, sequence: u16, payload: &[u8]) -> ModuleFrame {
        let mut taxels = [[0; 3]; MAX_TAXELS];
        let count = payload.len() / TAXEL_BYTES;
        for (taxel, b) in taxels.iter_mut().zip(payload.chunks_exact(TAXEL_BYTES)) {
            *taxel = [
                u16::from_be_bytes([b[0], b[1]]),
                u16::from_be_bytes([b[2], b[3]]),
                u16::from_be_bytes([b[4], b[5]]),
            ];
        }
        ModuleFrame { module, sequence, count: count as u8, taxels }
    }
}

/// What the decoder found in the stream.
#[expect(
    clippy::large_enum_variant,
    reason = "frames are nearly every event: boxing them would allocate per frame to shrink the rare error events"
)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SerialEvent {
    /// A frame with a good CRC.
    Frame(ModuleFrame),
    /// The decoder discarded bytes to find the next frame boundary; the frame
    /// that follows this event is the first one in sync again.
    Resync {
        /// Bytes discarded since the last good frame.
        skipped_bytes: u64,
    },
    /// A frame that arrived in sync failed its CRC and was dropped.
    BadCrc {
        /// The module id in its header (may be corrupt too).
        module: u8,
        /// The sequence counter in its header (may be corrupt too).
        sequence: u16,
        /// The CRC of the bytes received.
        expected: u16,
        /// The CRC the frame carried.
        got: u16,
    },
    /// A module's sequence counter did not follow on from its previous frame
    /// (frames lost, repeated or reordered); the frame follows this event.
    Gap {
        /// The module.
        module: u8,
        /// The counter that would have followed the previous frame.
        expected: u16,
        /// The counter received.
        got: u16,
    },
}

/// Finds frames in a byte stream, without I/O.
///
/// # Contract
/// - [`push`](Self::push) copies as many bytes as fit (never more than
///   [`DECODER_CAPACITY`] are held) and returns how many it took; drain
///   [`next_event`](Self::next_event) until `None` before pushing the rest.
///   [`feed`](Self::feed) does both for a whole slice.
/// - Any byte stream is accepted: garbage, truncated or corrupted frames and
///   frames cut anywhere between pushes. No input panics.
/// - Events come in stream order; [`SerialEvent::Resync`] and
///   [`SerialEvent::Gap`] precede the frame they concern.
/// - A candidate frame that fails its CRC while the decoder is in sync is a
///   CRC error; candidates tried while resynchronising (sync bytes that turn
///   out to be payload) are part of the resync and are not counted.
/// - A candidate cut short waits for the rest of its bytes, which may hold
///   whole frames when its length field was garbage. At the end of a stream
///   (a capture file), [`finish`](Self::finish) says no more bytes will
///   come: the decoder then looks for frames after the cut candidate's sync
///   bytes, and only an unfinishable tail stays [`buffered`](Self::buffered).
pub struct SerialDecoder {
    buf: Box<[u8]>,
    start: usize,
    end: usize,
    in_sync: bool,
    at_end: bool,
    skipped: u64,
    last_sequence: Box<[Option<u16>; 256]>,
    queued: [Option<SerialEvent>; 2],
    counters: DecoderCounters,
}

impl Default for SerialDecoder {
    fn default() -> Self {
        SerialDecoder::new()
    }
}

impl SerialDecoder {
    /// A decoder at the start of a stream.
    pub fn new() -> SerialDecoder {
        SerialDecoder {
            buf: vec![0; DECODER_CAPACITY].into_boxed_slice(),
            start: 0,
            end: 0,
            in_sync: true,
            at_end: false,
            skipped: 0,
            last_sequence: Box::new([None; 256]),
            queued: [None, None],
            counters: DecoderCounters::default(),
        }
    }

    /// Takes as many of `bytes` as fit in the buffer; returns how many.
    /// Pushing bytes after [`finish`](Self::finish) continues the stream.
    pub fn push(&mut self, bytes: &[u8]) -> usize {
        if !bytes.is_empty() {
            self.at_end = false;
        }
        if self.start > 0 && self.buf.len() - self.end < bytes.len() {
            self.buf.copy_within(self.start..self.end, 0);
            self.end -= self.start;
            self.start = 0;
        }
        let n = bytes.len().min(self.buf.len() - self.end);
        self.buf[self.end..self.end + n].copy_from_slice(&bytes[..n]);
        self.end += n;
        n
    }

    /// Pushes all of `bytes`, calling `on_event` for every event on the way.
    pub fn feed(&mut self, mut bytes: &[u8], mut on_event: impl FnMut(SerialEvent)) {
        loop {
            let n = self.push(bytes);
            bytes = &bytes[n..];
            while let Some(event) = self.next_event() {
                on_event(event);
            }
            if bytes.is_empty() {
                return;
            }
        }
    }

    /// Declares the end of the stream: a frame cut short will never be
    /// completed, so [`next_event`](Self::next_event) goes on to the frames
    /// that may follow its sync bytes. Drain `next_event` afterwards.
    pub fn finish(&mut self) {
        self.at_end = true;
    }

    /// The counters so far.
    pub fn counters(&self) -> DecoderCounters {
        self.counters
    }

    /// Bytes held, waiting for the rest of a frame.
    pub fn buffered(&self) -> usize {
        self.end - self.start
    }

    fn discard(&mut self, n: usize) {
        self.start += n;
        self.skipped += n as u64;
        self.counters.bytes_skipped += n as u64;
    }

    /// The next event, or `None` when the buffered bytes hold no more.
    pub fn next_event(&mut self) -> Option<SerialEvent> {
        if let Some(event) = self.queued.iter_mut().find_map(Option::take) {
            return Some(event);
        }
        loop {
            let avail = &self.buf[self.start..self.end];
            if avail.len() < SYNC.len() {
                if avail.first().is_some_and(|&b| b != SYNC[0]) {
                    self.in_sync = false;
                    self.discard(1);
                }
                return None;
            }
            if avail[..2] != SYNC {
                let skip = next_start(avail).unwrap_or(avail.len());
                self.in_sync = false;
                self.discard(skip);
                continue;
            }
            if avail.len() < HEADER_LEN {
                if self.skip_cut_candidate() {
                    continue;
                }
                return None;
            }
            let payload_len = usize::from(u16::from_be_bytes([avail[2], avail[3]]));
            if payload_len == 0 || payload_len % TAXEL_BYTES != 0 || payload_len > MAX_TAXELS * TAXEL_BYTES {
                self.in_sync = false;
                self.discard(1);
                continue;
            }
            let total = HEADER_LEN + payload_len + CRC_LEN;
            if avail.len() < total {
                if self.skip_cut_candidate() {
                    continue;
                }
                return None;
            }
            let module = avail[4];
            let sequence = u16::from_be_bytes([avail[5], avail[6]]);
            let got = u16::from_be_bytes([avail[total - 2], avail[total - 1]]);
            let expected = crc16(&avail[2..total - CRC_LEN]);
            if got != expected {
                let was_in_sync = self.in_sync;
                self.in_sync = false;
                self.discard(1);
                if was_in_sync {
                    self.counters.crc_errors += 1;
                    return Some(SerialEvent::BadCrc { module, sequence, expected, got });
                }
                continue;
            }
            let frame = ModuleFrame::parse(module, sequence, &avail[HEADER_LEN..HEADER_LEN + payload_len]);
            self.start += total;
            return Some(self.accept(frame));
        }
    }

    /// At the end of the stream, discards a candidate frame that was cut
    /// short up to the next possible start; false when there is none (or the
    /// stream goes on).
    fn skip_cut_candidate(&mut self) -> bool {
        let Some(skip) = self.at_end.then(|| next_start(&self.buf[self.start..self.end])).flatten() else {
            return false;
        };
        self.in_sync = false;
        self.discard(skip);
        true
    }

    /// Counts a good frame; returns the first of its events and queues the rest.
    fn accept(&mut self, frame: ModuleFrame) -> SerialEvent {
        self.counters.frames += 1;
        self.in_sync = true;
        let mut events = [None, None, None];
        let mut n = 0;
        if self.skipped > 0 {
            self.counters.resyncs += 1;
            events[n] = Some(SerialEvent::Resync { skipped_bytes: self.skipped });
            n += 1;
            self.skipped = 0;
        }
        let last = &mut self.last_sequence[usize::from(frame.module)];
        if let Some(previous) = *last {
            let expected = previous.wrapping_add(1);
            if frame.sequence != expected {
                self.counters.gaps += 1;
                events[n] = Some(SerialEvent::Gap { module: frame.module, expected, got: frame.sequence });
                n += 1;
            }
        }
        *last = Some(frame.sequence);
        events[n] = Some(SerialEvent::Frame(frame));
        let [first, second, third] = events;
        self.queued = [second, third];
        // `first` is always set: it is the frame when nothing precedes it.
        first.unwrap_or(SerialEvent::Frame(frame))
    }
}

/// The next possible frame start after the first byte of `avail`: a first
/// sync byte followed by the second, or a first sync byte at the very end.
fn next_start(avail: &[u8]) -> Option<usize> {
    (1..avail.len()).find(|&i| avail[i] == SYNC[0] && avail.get(i + 1).is_none_or(|&b| b == SYNC[1]))
}

#[cfg(test)]
mod tests;
