//! Counters kept by the tactile decoders, recorded on `/tactile/decoder`.

use serde::{Deserialize, Serialize};

/// What a tactile decoder has seen since it started: frames decoded and the
/// ways the stream went wrong. Every counter only grows.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct DecoderCounters {
    /// Frames decoded intact (serial: module frames with a good CRC; CAN:
    /// taxel frames of the configured board).
    pub frames: u64,
    /// Frames that arrived in sync but failed their CRC (serial only; CAN
    /// checks its CRC in the controller).
    pub crc_errors: u64,
    /// Times the decoder lost the frame boundaries and found them again by
    /// discarding bytes (serial only).
    pub resyncs: u64,
    /// Bytes discarded while looking for a frame boundary (serial only).
    pub bytes_skipped: u64,
    /// Breaks in a module's sequence counter: frames lost, repeated or
    /// reordered on the way (serial only; CAN frames carry no counter).
    pub gaps: u64,
    /// Scans that lacked a frame (or whose mapped taxel was invalid) and were
    /// dropped rather than emitted half-filled.
    pub incomplete_scans: u64,
    /// Taxel samples the sensor itself marked invalid (CAN: first data byte
    /// of 250 or more) or that were too short to hold x, y and z.
    pub invalid_samples: u64,
}

impl DecoderCounters {
    /// True when any error counter differs from `other`'s (frames aside).
    pub fn errors_differ(&self, other: &DecoderCounters) -> bool {
        let errors = |c: &DecoderCounters| {
            [c.crc_errors, c.resyncs, c.bytes_skipped, c.gaps, c.incomplete_scans, c.invalid_samples]
        };
        errors(self) != errors(other)
    }

    /// Sum of the error counters that lose data (CRC errors, gaps, incomplete
    /// scans, invalid samples), for summaries.
    pub fn data_errors(&self) -> u64 {
        self.crc_errors + self.gaps + self.incomplete_scans + self.invalid_samples
    }
}

impl std::fmt::Display for DecoderCounters {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} frames, {} CRC errors, {} resyncs ({} bytes skipped), {} gaps, {} incomplete scans, {} invalid samples",
            self.frames,
            self.crc_errors,
            self.resyncs,
            self.bytes_skipped,
            self.gaps,
            self.incomplete_scans,
            self.invalid_samples
        )
    }
}
