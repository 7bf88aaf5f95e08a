//! From module frames to fingertip scans: which taxel of which module each
//! finger reads, and the assembly of the frames of one scan.

use slidetrack_core::{Finger, PerFinger, RawTaxel, TaxelRef};

use crate::serial_protocol::ModuleFrame;

/// Which taxel of which module each finger's `[x, y, z]` comes from,
/// indexed by [`Finger::index`].
pub type FingerTaxels = [TaxelRef; 3];

/// The default map: one module per finger (thumb 0, index 1, middle 2), taxel 0 of each.
pub fn default_finger_taxels() -> PerFinger<TaxelRef> {
    PerFinger::from_fn(|f| TaxelRef { module: f.index() as u32, taxel: 0 })
}

/// Assembles the module frames of one scan (same sequence counter) into the
/// three fingers' values.
///
/// # Contract
/// - A scan is emitted as soon as every module the map names has delivered
///   its frame for that sequence number; frames of other modules are ignored.
/// - A frame with a different sequence number while a scan is partly filled
///   ends that scan: it is counted in [`incomplete_scans`](Self::incomplete_scans)
///   and never emitted half-filled.
/// - A module whose frame is too short for its mapped taxel never completes
///   a scan; [`short_module`](Self::short_module) says which.
pub struct ModuleScanAssembler {
    fingers: FingerTaxels,
    current: Option<u16>,
    filled: [Option<RawTaxel>; 3],
    incomplete: u64,
    short: Option<(u32, u32, usize)>,
}

impl ModuleScanAssembler {
    /// An assembler for the fingers' `map`.
    pub fn new(map: &PerFinger<TaxelRef>) -> ModuleScanAssembler {
        ModuleScanAssembler {
            fingers: map.into_array(),
            current: None,
            filled: [None; 3],
            incomplete: 0,
            short: None,
        }
    }

    /// Feeds one frame; returns `(sequence, [thumb, index, middle])` when it completes a scan.
    pub fn push(&mut self, frame: &ModuleFrame) -> Option<(u16, [RawTaxel; 3])> {
        let module = u32::from(frame.module);
        if !self.fingers.iter().any(|r| r.module == module) {
            return None;
        }
        if self.current != Some(frame.sequence) {
            if self.filled.iter().any(Option::is_some) {
                self.incomplete += 1;
            }
            self.filled = [None; 3];
            self.current = Some(frame.sequence);
        }
        for f in Finger::ALL {
            let r = self.fingers[f.index()];
            if r.module != module {
                continue;
            }
            match frame.taxels().get(r.taxel as usize) {
                Some(v) => self.filled[f.index()] = Some(*v),
                None => self.short = Some((module, r.taxel, frame.taxels().len())),
            }
        }
        if let [Some(a), Some(b), Some(c)] = self.filled {
            self.filled = [None; 3];
            self.current = None;
            return Some((frame.sequence, [a, b, c]));
        }
        None
    }

    /// Scans dropped because a frame was missing.
    pub fn incomplete_scans(&self) -> u64 {
        self.incomplete
    }

    /// `(module, mapped taxel, taxels in its frames)` when a module's frames
    /// are too short for the taxel the map names.
    pub fn short_module(&self) -> Option<(u32, u32, usize)> {
        self.short
    }
}

/// Extends a wrapping 16-bit counter to 64 bits: steps forward of less than
/// half the range count as forward, larger ones as backward (never below 0).
#[derive(Clone, Copy, Debug, Default)]
pub struct SequenceUnwrapper {
    last: Option<(u16, u64)>,
}

impl SequenceUnwrapper {
    /// The 64-bit value of `sequence`.
    pub fn unwrap(&mut self, sequence: u16) -> u64 {
        let value = match self.last {
            None => u64::from(sequence),
            Some((last16, last)) => {
                let step = sequence.wrapping_sub(last16) as i16;
                last.saturating_add_signed(i64::from(step))
            }
        };
        self.last = Some((sequence, value));
        value
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn map() -> PerFinger<TaxelRef> {
        PerFinger {
            thumb: TaxelRef { module: 0, taxel: 3 },
            index: TaxelRef { module: 2, taxel: 0 },
            middle: TaxelRef { module: 2, taxel: 1 },
        }
    }

    fn frame(module: u8, sequence: u16) -> ModuleFrame {
        let taxels: Vec<RawTaxel> = (0..4).map(|t| [u16::from(module) * 100 + t, sequence, 7]).collect();
        ModuleFrame::new(module, sequence, &taxels).unwrap()
    }

    #[test]
    fn a_scan_completes_when_every_mapped_module_has_sent_its_frame() {
        let mut a = ModuleScanAssembler::new(&map());
        assert_eq!(a.push(&frame(0, 5)), None);
        assert_eq!(a.push(&frame(1, 5)), None, "module 1 is not mapped");
        assert_eq!(a.push(&frame(2, 5)), Some((5, [[3, 5, 7], [200, 5, 7], [201, 5, 7]])));
        // The other order works too.
        assert_eq!(a.push(&frame(2, 6)), None);
        assert_eq!(a.push(&frame(0, 6)), Some((6, [[3, 6, 7], [200, 6, 7], [201, 6, 7]])));
        assert_eq!(a.incomplete_scans(), 0);
    }

    #[test]
    fn a_missing_frame_drops_the_scan_and_counts_it() {
        let mut a = ModuleScanAssembler::new(&map());
        assert_eq!(a.push(&frame(0, 1)), None);
        // Module 2's frame of scan 1 was lost.
        assert_eq!(a.push(&frame(0, 2)), None);
        assert_eq!(a.incomplete_scans(), 1);
        assert!(a.push(&frame(2, 2)).is_some());
        // A late frame of an old scan starts a scan that cannot complete.
        assert_eq!(a.push(&frame(2, 1)), None);
        assert_eq!(a.push(&frame(0, 3)), None);
        assert_eq!(a.incomplete_scans(), 2);
    }

    #[test]
    fn a_frame_too_short_for_the_map_is_reported() {
        let mut m = map();
        m.thumb.taxel = 9;
        let mut a = ModuleScanAssembler::new(&m);
        assert_eq!(a.push(&frame(0, 1)), None);
        assert_eq!(a.push(&frame(2, 1)), None);
        assert_eq!(a.short_module(), Some((0, 9, 4)));
    }

    #[test]
    fn sequences_unwrap_across_the_16_bit_boundary() {
        let mut u = SequenceUnwrapper::default();
        assert_eq!(u.unwrap(65534), 65534);
        assert_eq!(u.unwrap(65535), 65535);
        assert_eq!(u.unwrap(0), 65536);
        assert_eq!(u.unwrap(5), 65541);
        assert_eq!(u.unwrap(3), 65539, "a step back");
        let mut u = SequenceUnwrapper::default();
        assert_eq!(u.unwrap(2), 2);
        assert_eq!(u.unwrap(65535), 0, "never below zero");
    }
}
