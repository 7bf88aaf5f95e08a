//! From module frames to scans: the frames of one scan (same sequence
//! counter) joined into every taxel of every configured sensor.

use slidetrack_core::RawTaxel;

use crate::serial::protocol::ModuleFrame;

/// Assembles the module frames of one scan (same sequence counter) into a
/// scan of every configured sensor: the first `taxels` taxels of each
/// sensor's module frame, sensors in configuration order.
///
/// # Contract
/// - A scan is emitted as soon as every configured module has delivered its
///   frame for that sequence number; frames of other modules are ignored.
/// - A frame with a different sequence number while a scan is partly filled
///   ends that scan: it is counted in [`incomplete_scans`](Self::incomplete_scans)
///   and never emitted half-filled.
/// - A module whose frame has fewer taxels than its sensor never completes
///   a scan; [`short_module`](Self::short_module) says which.
pub struct ModuleScanAssembler {
    /// Per sensor: its module and taxel count.
    sensors: Vec<(u32, usize)>,
    current: Option<u16>,
    filled: Vec<Option<Vec<RawTaxel>>>,
    incomplete: u64,
    short: Option<(u32, usize, usize)>,
}

impl ModuleScanAssembler {
    /// An assembler of the sensors `(module, taxels)`, in scan order.
    pub fn new(sensors: &[(u32, usize)]) -> ModuleScanAssembler {
        ModuleScanAssembler {
            sensors: sensors.to_vec(),
            current: None,
            filled: vec![None; sensors.len()],
            incomplete: 0,
            short: None,
        }
    }

    /// Adds a frame; returns `(sequence, every taxel of the scan)` when it completes one.
    pub fn push(&mut self, frame: &ModuleFrame) -> Option<(u16, Vec<RawTaxel>)> {
        let module = u32::from(frame.module);
        let slot = self.sensors.iter().position(|(m, _)| *m == module)?;
        if self.current != Some(frame.sequence) {
            if self.filled.iter().any(Option::is_some) {
                self.incomplete += 1;
            }
            self.filled.iter_mut().for_each(|f| *f = None);
            self.current = Some(frame.sequence);
        }
        let taxels = self.sensors[slot].1;
        match frame.taxels().get(..taxels) {
            Some(values) => self.filled[slot] = Some(values.to_vec()),
            None => self.short = Some((module, taxels, frame.taxels().len())),
        }
        if self.filled.iter().all(Option::is_some) {
            let scan = self.filled.iter_mut().flat_map(|f| f.take().unwrap_or_default()).collect();
            self.current = None;
            return Some((frame.sequence, scan));
        }
        None
    }

    /// Scans dropped because a module's frame was missing.
    pub fn incomplete_scans(&self) -> u64 {
        self.incomplete
    }

    /// `(module, taxels needed, taxels in its frames)` of a module whose
    /// frames are too short for its sensor, if one was seen.
    pub fn short_module(&self) -> Option<(u32, usize, usize)> {
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

    /// Sensors on modules 0 (4 taxels) and 2 (2 taxels).
    fn sensors() -> Vec<(u32, usize)> {
        vec![(0, 4), (2, 2)]
    }

    fn frame(module: u8, sequence: u16) -> ModuleFrame {
        let taxels: Vec<RawTaxel> = (0..4).map(|t| [u16::from(module) * 100 + t, sequence, 7]).collect();
        ModuleFrame::new(module, sequence, &taxels).unwrap()
    }

    #[test]
    fn a_scan_completes_when_every_configured_module_has_sent_its_frame() {
        let mut a = ModuleScanAssembler::new(&sensors());
        assert_eq!(a.push(&frame(0, 5)), None);
        assert_eq!(a.push(&frame(1, 5)), None, "module 1 is not configured");
        let scan = vec![[0, 5, 7], [1, 5, 7], [2, 5, 7], [3, 5, 7], [200, 5, 7], [201, 5, 7]];
        assert_eq!(a.push(&frame(2, 5)), Some((5, scan)));
        assert_eq!(a.push(&frame(2, 6)), None);
        assert_eq!(a.push(&frame(0, 6)).map(|(s, v)| (s, v.len())), Some((6, 6)), "in sensor order");
        assert_eq!(a.incomplete_scans(), 0);
    }

    #[test]
    fn a_missing_frame_drops_the_scan_and_counts_it() {
        let mut a = ModuleScanAssembler::new(&sensors());
        assert_eq!(a.push(&frame(0, 1)), None);
        assert_eq!(a.push(&frame(0, 2)), None);
        assert_eq!(a.incomplete_scans(), 1);
        assert!(a.push(&frame(2, 2)).is_some());
        assert_eq!(a.push(&frame(2, 1)), None);
        assert_eq!(a.push(&frame(0, 3)), None);
        assert_eq!(a.incomplete_scans(), 2);
    }

    #[test]
    fn a_frame_too_short_for_its_sensor_is_reported() {
        let mut a = ModuleScanAssembler::new(&[(0, 9), (2, 2)]);
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
