//! Arbitrary CAN frames (id, length, data, time step) into the scan
//! assembler: no panic, and every scan it emits is whole.

#![no_main]

use std::time::Duration;

use libfuzzer_sys::fuzz_target;
use slidetrack_core::TimeNs;
use slidetrack_drivers::can_protocol::{CanFrame, CanScanAssembler, XelaCanLayout};

fuzz_target!(|data: &[u8]| {
    let Some((&taxels, mut rest)) = data.split_first() else { return };
    let layout = XelaCanLayout { taxels: u16::from(taxels % 64).max(1), ..XelaCanLayout::default() };
    let mut assembler = CanScanAssembler::new(layout, Duration::from_millis(5));
    let mut t = 0u64;
    // Each frame: id offset, length, time step, then up to 8 data bytes.
    while let [id, len, step, tail @ ..] = rest {
        let len = usize::from(*len % 9).min(tail.len());
        let (payload, next) = tail.split_at(len);
        rest = next;
        t += u64::from(*step) * 100_000;
        let Some(frame) = CanFrame::standard(0x700 + u32::from(*id % 0x80), payload) else { continue };
        if let Some(scan) = assembler.push(TimeNs(t), &frame) {
            assert_eq!(scan.taxels.len(), usize::from(layout.taxels));
        }
        assert!(assembler.pending() < usize::from(layout.taxels));
    }
});
