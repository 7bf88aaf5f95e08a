//! Captured CAN traffic turned into tactile samples, for `slidetrack
//! decode`: can-utils `candump -l` logs and candump's console output, read
//! as a stream with bounded memory.

use std::io::{BufRead, BufReader, Read};

use slidetrack_core::{DecoderCounters, TactileSample, TimeNs};

use crate::can::candump::{self, CandumpFrame, CandumpRecord};
use crate::can::config::CanTactileConfig;
use crate::can::layout::{CanLayoutDecoder, CanMapError};
use crate::can::protocol::CanFrame;

/// Decodes a `candump -l` log (`(1700000000.123456) can0 710#00123456789ABC`)
/// or candump's console output (`  can0  710   [7]  00 12 ...`, with or
/// without `-t a`/`-t z`/`-t d` times) into the scans of the configured
/// layout.
///
/// # Contract
/// - Sample times are the log's timestamps relative to its first frame
///   (session clock starting at 0), made non-decreasing; with
///   [`with_deltas`](Self::with_deltas) each time is the gap since the
///   previous frame (`candump -t d`). Lines without a time take the
///   previous frame's time plus `1 / (rate_hz * taxels)`: log order, spaced
///   as if the board ran at `rate_hz` (nothing in the log says otherwise).
/// - Lines that do not parse are counted ([`CanLogDecoder::bad_lines`]) and
///   skipped; frames of other ids and interfaces are ignored.
pub struct CanLogDecoder<R: Read> {
    reader: BufReader<R>,
    line: String,
    interface: Option<String>,
    decoder: CanLayoutDecoder,
    /// Time step of a frame without a time (ns).
    untimed_step_ns: u64,
    deltas: bool,
    untimed: u64,
    first_us: Option<u64>,
    last_t: TimeNs,
    lines: u64,
    bad_lines: u64,
    first_error: Option<(u64, String)>,
}

impl<R: Read> CanLogDecoder<R> {
    /// A decoder of the log in `input` for the board of `cfg`; frames of
    /// interfaces other than `interface` are skipped when it is given.
    pub fn new(
        input: R,
        cfg: &CanTactileConfig,
        interface: Option<String>,
    ) -> Result<CanLogDecoder<R>, CanMapError> {
        let layout = cfg.layout()?;
        let per_scan = layout.slots.len().max(1) as f64;
        let rate_hz = if cfg.rate_hz.is_finite() && cfg.rate_hz > 0.0 { cfg.rate_hz } else { 100.0 };
        Ok(CanLogDecoder {
            reader: BufReader::new(input),
            line: String::new(),
            interface,
            decoder: CanLayoutDecoder::new(layout, cfg.rate_hz),
            untimed_step_ns: (1e9 / (rate_hz * per_scan)) as u64,
            deltas: false,
            untimed: 0,
            first_us: None,
            last_t: TimeNs::ZERO,
            lines: 0,
            bad_lines: 0,
            first_error: None,
        })
    }

    /// Reads the times as gaps since the previous frame (`candump -t d`).
    pub fn with_deltas(mut self, deltas: bool) -> CanLogDecoder<R> {
        self.deltas = deltas;
        self
    }

    /// The decoder counters so far.
    pub fn counters(&self) -> DecoderCounters {
        self.decoder.counters()
    }

    /// Frames that had no time in the log.
    pub fn untimed_frames(&self) -> u64 {
        self.untimed
    }

    /// Lines read so far.
    pub fn lines(&self) -> u64 {
        self.lines
    }

    /// Lines that did not parse as candump records.
    pub fn bad_lines(&self) -> u64 {
        self.bad_lines
    }

    /// The first line that did not parse: `(line number, why)`.
    pub fn first_error(&self) -> Option<&(u64, String)> {
        self.first_error.as_ref()
    }

    fn frame(&mut self, record: CandumpRecord) -> Option<(TimeNs, CanFrame)> {
        if self.interface.as_ref().is_some_and(|i| *i != record.interface) {
            return None;
        }
        let CandumpFrame::Data { id, extended, data } = record.frame else { return None };
        let frame = CanFrame::new(id, extended, &data)?;
        let t = match record.t_us {
            None => {
                self.untimed += 1;
                TimeNs(self.last_t.0.saturating_add(self.untimed_step_ns))
            }
            Some(us) if self.deltas => TimeNs(self.last_t.0.saturating_add(us.saturating_mul(1000))),
            Some(us) => {
                let first = *self.first_us.get_or_insert(us);
                TimeNs(us.saturating_sub(first).saturating_mul(1000)).max(self.last_t)
            }
        };
        self.last_t = t;
        Some((t, frame))
    }
}

impl<R: Read> Iterator for CanLogDecoder<R> {
    type Item = TactileSample;

    fn next(&mut self) -> Option<TactileSample> {
        loop {
            self.line.clear();
            match self.reader.read_line(&mut self.line) {
                Ok(0) => return None,
                Ok(_) => self.lines += 1,
                Err(e) if e.kind() == std::io::ErrorKind::InvalidData => {
                    // Not UTF-8 (the line is consumed): not a candump record.
                    self.lines += 1;
                    self.bad_lines += 1;
                    self.first_error.get_or_insert((self.lines, e.to_string()));
                    continue;
                }
                Err(e) => {
                    self.lines += 1;
                    self.first_error.get_or_insert((self.lines, e.to_string()));
                    return None;
                }
            }
            let text = self.line.trim_end_matches(['\n', '\r']);
            if text.trim().is_empty() {
                continue;
            }
            let record = match candump::parse_any_line(text) {
                Ok(r) => r,
                Err(e) => {
                    self.bad_lines += 1;
                    self.first_error.get_or_insert((self.lines, e.to_string()));
                    continue;
                }
            };
            let Some((t, frame)) = self.frame(record) else { continue };
            if let Some(scan) = self.decoder.push(t, &frame) {
                return Some(TactileSample::new(scan.t, scan.sequence, scan.taxels));
            }
        }
    }
}

/// One line of a `candump -l` log for `frame` received at `t_us` (µs since
/// the Unix epoch) on `interface`, without the newline.
pub fn candump_line(t_us: u64, interface: &str, frame: &CanFrame) -> String {
    candump::format_line(t_us, interface, frame.id, frame.extended, frame.data())
}

#[cfg(test)]
mod tests;
