//! Arbitrary bytes as a CAN log (`candump -l` records and candump's
//! console output mixed) into the offline decoder: no panic, times never
//! decrease.

#![no_main]

use libfuzzer_sys::fuzz_target;
use slidetrack_drivers::config::CanTactileConfig;
use slidetrack_drivers::can::log::CanLogDecoder;

fuzz_target!(|data: &[u8]| {
    let Some((&deltas, text)) = data.split_first() else { return };
    for line in String::from_utf8_lossy(text).lines() {
        let _ = slidetrack_drivers::can::candump::parse_any_line(line);
    }
    let Ok(decoder) = CanLogDecoder::new(text, &CanTactileConfig::default(), None) else { return };
    let mut last = slidetrack_core::TimeNs::ZERO;
    for sample in decoder.with_deltas(deltas & 1 == 1) {
        assert!(sample.t >= last);
        last = sample.t;
    }
});
