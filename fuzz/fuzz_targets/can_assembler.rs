//! Arbitrary CAN frames (id, length, data, time step) into the layout
//! decoder, in the legacy layout and a map, in both scan modes: no panic,
//! and every scan it emits is whole.

#![no_main]

use libfuzzer_sys::fuzz_target;
use slidetrack_core::TimeNs;
use slidetrack_drivers::can::layout::{CanLayoutDecoder, MapEntry, ScanMode};
use slidetrack_drivers::can::protocol::CanFrame;
use slidetrack_drivers::config::CanTactileConfig;

fuzz_target!(|data: &[u8]| {
    let Some((&mode, mut rest)) = data.split_first() else { return };
    let mut cfg = CanTactileConfig::default();
    if mode & 1 == 1 {
        cfg.map = ["thumb", "index", "middle"]
            .iter()
            .enumerate()
            .map(|(k, s)| MapEntry { sensor: (*s).into(), first_id: Some(0x700 + 0x20 * k as u32), ..MapEntry::default() })
            .collect();
    }
    cfg.scan_mode = if mode & 2 == 2 { ScanMode::Latest } else { ScanMode::Complete };
    let Ok(layout) = cfg.layout() else { return };
    let n = layout.slots.len();
    let mut decoder = CanLayoutDecoder::new(layout, cfg.rate_hz);
    let mut t = 0u64;
    // Each frame: id offset, length, time step, then up to 8 data bytes.
    while let [id, len, step, tail @ ..] = rest {
        let len = usize::from(*len % 9).min(tail.len());
        let (payload, next) = tail.split_at(len);
        rest = next;
        t += u64::from(*step) * 100_000;
        let Some(frame) = CanFrame::standard(0x700 + u32::from(*id % 0x80), payload) else { continue };
        for scan in decoder.push(TimeNs(t), &frame).into_iter().chain(decoder.poll(TimeNs(t))) {
            assert_eq!(scan.taxels.len(), n);
        }
        assert!(decoder.pending() <= n);
    }
});
