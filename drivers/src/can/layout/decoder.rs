//! Frames in, scans out, for any [`ResolvedLayout`]: no I/O, no clock of its
//! own (the caller passes each frame's receive time), counters kept.

use slidetrack_core::{DecoderCounters, RawTaxel, TimeNs};

use super::payload::Payload;
use super::resolved::{ResolvedLayout, ScanMode};
use crate::can::protocol::CanFrame;

/// One scan: every mapped taxel, in slot order.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct LayoutScan {
    /// Complete mode: receive time of the frame that completed the scan.
    /// Latest mode: the time passed to the call that emitted it.
    pub t: TimeNs,
    /// Complete mode: index of the scan among those begun, from 0
    /// (dropped ones count). Latest mode: index of the emission.
    pub sequence: u64,
    /// Every taxel's `[x, y, z]` raw counts.
    pub taxels: Vec<RawTaxel>,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Slot {
    Missing,
    Valid(RawTaxel),
    Invalid,
}

/// Assembles taxel frames into scans.
///
/// # Contract
/// - Frames of unmapped ids are ignored (not counted as taxel frames).
/// - [`ScanMode::Complete`]: a scan is emitted as soon as every slot holds
///   a valid value. A new scan begins with the first slot's frame, with a
///   frame of the scan-start id, or with a slot that already has a value;
///   the scan it replaces, if unfinished, is counted in `incomplete_scans`
///   and dropped. A scan with a sample marked invalid is dropped the same
///   way when it completes. No timing rule: frames may take any time.
/// - [`ScanMode::Latest`]: every frame updates its slot's latest valid
///   value; [`push`](Self::push) and [`poll`](Self::poll) emit a scan of
///   the latest values when every slot has had a valid value and `period`
///   has passed since the last emission (the first: at once).
/// - Samples marked invalid or too short are counted in `invalid_samples`.
/// - Memory: one slot per mapped taxel.
pub struct CanLayoutDecoder {
    layout: ResolvedLayout,
    period_ns: u64,
    slots: Vec<Slot>,
    filled: usize,
    begun: u64,
    next_emit: Option<TimeNs>,
    counters: DecoderCounters,
}

impl CanLayoutDecoder {
    /// A decoder of `layout`; `rate_hz` sets the latest mode's emission rate.
    pub fn new(layout: ResolvedLayout, rate_hz: f64) -> CanLayoutDecoder {
        let period_s = if rate_hz.is_finite() && rate_hz > 0.0 { 1.0 / rate_hz } else { 0.01 };
        let n = layout.slots.len();
        CanLayoutDecoder {
            layout,
            period_ns: (period_s * 1e9) as u64,
            slots: vec![Slot::Missing; n],
            filled: 0,
            begun: 0,
            next_emit: None,
            counters: DecoderCounters::default(),
        }
    }

    /// The layout.
    pub fn layout(&self) -> &ResolvedLayout {
        &self.layout
    }

    /// The counters so far.
    pub fn counters(&self) -> DecoderCounters {
        self.counters
    }

    /// Slots filled in the current scan (complete mode) or ever (latest mode).
    pub fn pending(&self) -> usize {
        self.filled
    }

    /// Feeds one frame received at `t`; returns the scan it completes
    /// (complete mode) or a due scan (latest mode).
    pub fn push(&mut self, t: TimeNs, frame: &CanFrame) -> Option<LayoutScan> {
        let key = (frame.id, frame.extended);
        if self.layout.mode == ScanMode::Complete && self.layout.scan_start_id == Some(key) {
            self.begin();
            return None;
        }
        let Some(&slot) = self.layout.by_id.get(&key) else {
            return if self.layout.mode == ScanMode::Latest { self.poll(t) } else { None };
        };
        self.counters.frames += 1;
        let value = match self.layout.payload.decode(frame.data()) {
            Payload::Valid(v) => Slot::Valid(v),
            Payload::Invalid | Payload::TooShort => {
                self.counters.invalid_samples += 1;
                Slot::Invalid
            }
        };
        match self.layout.mode {
            ScanMode::Complete => self.push_complete(t, slot, value),
            ScanMode::Latest => {
                if let Slot::Valid(_) = value {
                    if self.slots[slot] == Slot::Missing {
                        self.filled += 1;
                    }
                    self.slots[slot] = value;
                }
                self.poll(t)
            }
        }
    }

    /// Latest mode: the scan due at `t`, if every taxel has been seen.
    /// Complete mode: always `None`.
    pub fn poll(&mut self, t: TimeNs) -> Option<LayoutScan> {
        if self.layout.mode != ScanMode::Latest || self.filled < self.slots.len() {
            return None;
        }
        if self.next_emit.is_some_and(|next| t < next) {
            return None;
        }
        let next = self.next_emit.map_or(t.0, |n| n.0).saturating_add(self.period_ns);
        // Late by a period or more: skip ahead rather than emit a burst.
        self.next_emit = Some(TimeNs(if next <= t.0 { t.0.saturating_add(self.period_ns) } else { next }));
        let scan = LayoutScan { t, sequence: self.begun, taxels: self.values()? };
        self.begun += 1;
        Some(scan)
    }

    fn push_complete(&mut self, t: TimeNs, slot: usize, value: Slot) -> Option<LayoutScan> {
        if self.filled > 0 && (slot == 0 || self.slots[slot] != Slot::Missing) {
            self.begin();
        }
        if self.filled == 0 {
            self.begun += 1;
        }
        self.slots[slot] = value;
        self.filled += 1;
        if self.filled < self.slots.len() {
            return None;
        }
        let taxels = self.values();
        self.clear();
        match taxels {
            Some(taxels) => Some(LayoutScan { t, sequence: self.begun - 1, taxels }),
            None => {
                self.counters.incomplete_scans += 1;
                None
            }
        }
    }

    /// Ends the current scan: counted as incomplete when it had frames.
    fn begin(&mut self) {
        if self.filled > 0 {
            self.counters.incomplete_scans += 1;
            self.clear();
        }
    }

    fn values(&self) -> Option<Vec<RawTaxel>> {
        self.slots
            .iter()
            .map(|s| match s {
                Slot::Valid(v) => Some(*v),
                _ => None,
            })
            .collect()
    }

    fn clear(&mut self) {
        self.slots.fill(Slot::Missing);
        self.filled = 0;
    }

    /// Counts a scan the caller could not use.
    pub fn count_unusable_scan(&mut self) {
        self.counters.incomplete_scans += 1;
    }
}
