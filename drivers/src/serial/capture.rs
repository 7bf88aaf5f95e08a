//! A raw serial capture (the bytes as the port delivered them) turned into
//! tactile samples, for `slidetrack decode`, read as a stream with bounded
//! memory.

use std::io::Read;

use slidetrack_core::{DecoderCounters, TactileSample, TimeNs};

use crate::sensors::module_taxels;
use crate::serial::config::SerialTactileConfig;
use crate::serial::protocol::{SerialDecoder, SerialEvent};
use crate::serial::scan::{ModuleScanAssembler, SequenceUnwrapper};

/// Decodes a raw serial capture (the bytes as the port delivered them).
///
/// # Contract
/// - Sample times come from the board's scan counter at `rate_hz`,
///   relative to the first scan (the bytes carry no time of their own), made
///   non-decreasing.
/// - Reads the input in 64 KiB pieces; memory stays bounded whatever its size.
pub struct SerialCaptureDecoder<R: Read> {
    input: R,
    decoder: SerialDecoder,
    scans: CaptureScans,
    buf: Box<[u8]>,
    bytes: u64,
    finished: bool,
    error: Option<std::io::Error>,
}

/// Module frames of a capture turned into timed scans.
struct CaptureScans {
    assembler: ModuleScanAssembler,
    unwrapper: SequenceUnwrapper,
    period_ns: f64,
    first: Option<u64>,
    last_t: TimeNs,
    ready: std::collections::VecDeque<TactileSample>,
}

impl CaptureScans {
    fn on_event(&mut self, event: SerialEvent) {
        if let SerialEvent::Frame(frame) = event
            && let Some((sequence, raw)) = self.assembler.push(&frame)
        {
            let sequence = self.unwrapper.unwrap(sequence);
            let first = *self.first.get_or_insert(sequence);
            // A scan counter that steps back (reordered frames) does not take time back.
            let t = TimeNs((sequence.saturating_sub(first) as f64 * self.period_ns).round() as u64)
                .max(self.last_t);
            self.last_t = t;
            self.ready.push_back(TactileSample::new(t, sequence, raw));
        }
    }
}

impl<R: Read> SerialCaptureDecoder<R> {
    /// A decoder of the capture in `input` for the modules of `cfg`, timed at `rate_hz`.
    pub fn new(input: R, cfg: &SerialTactileConfig, rate_hz: f64) -> SerialCaptureDecoder<R> {
        SerialCaptureDecoder {
            input,
            decoder: SerialDecoder::new(),
            scans: CaptureScans {
                assembler: ModuleScanAssembler::new(&module_taxels(&cfg.sensors)),
                unwrapper: SequenceUnwrapper::default(),
                period_ns: 1e9 / rate_hz.max(1e-6),
                first: None,
                last_t: TimeNs::ZERO,
                ready: Default::default(),
            },
            buf: vec![0; 64 << 10].into_boxed_slice(),
            bytes: 0,
            finished: false,
            error: None,
        }
    }

    /// The decoder counters so far.
    pub fn counters(&self) -> DecoderCounters {
        DecoderCounters {
            incomplete_scans: self.scans.assembler.incomplete_scans(),
            ..self.decoder.counters()
        }
    }

    /// Bytes read so far.
    pub fn bytes(&self) -> u64 {
        self.bytes
    }

    /// Bytes at the end that did not complete a frame (once the input is exhausted).
    pub fn trailing_bytes(&self) -> usize {
        self.decoder.buffered()
    }

    /// The read error that ended the input early, if any.
    pub fn error(&self) -> Option<&std::io::Error> {
        self.error.as_ref()
    }
}

impl<R: Read> Iterator for SerialCaptureDecoder<R> {
    type Item = TactileSample;

    fn next(&mut self) -> Option<TactileSample> {
        loop {
            if let Some(s) = self.scans.ready.pop_front() {
                return Some(s);
            }
            if self.error.is_some() || self.finished {
                return None;
            }
            let n = match self.input.read(&mut self.buf) {
                Ok(0) => {
                    // The end of the capture: frames a cut one was hiding come out now.
                    self.finished = true;
                    self.decoder.finish();
                    while let Some(event) = self.decoder.next_event() {
                        self.scans.on_event(event);
                    }
                    continue;
                }
                Ok(n) => n,
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
                Err(e) => {
                    self.error = Some(e);
                    return None;
                }
            };
            self.bytes += n as u64;
            let scans = &mut self.scans;
            self.decoder.feed(&self.buf[..n], |event| scans.on_event(event));
        }
    }
}

#[cfg(test)]
mod tests;
