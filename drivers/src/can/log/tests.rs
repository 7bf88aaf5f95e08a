//! Decoding candump logs, including damaged ones.

use slidetrack_core::{FingerReading, PerFinger, RawTaxel};

use super::*;
use crate::can::protocol::XelaCanLayout;
use crate::sensors::HwSensor;

fn can_cfg() -> CanTactileConfig {
    CanTactileConfig {
        taxels: 16,
        taxels_per_module: 16,
        sensors: vec![HwSensor {
            name: "patch".into(),
            module: 0,
            finger: "thumb".into(),
            model: "uSPa44".into(),
            rows: 4,
            cols: 4,
            taxel_positions_mm: None,
        }],
        fingers: Some(PerFinger::from_fn(|_| FingerReading::mean("patch"))),
        ..CanTactileConfig::default()
    }
}

fn value(scan: u64, taxel: u16) -> RawTaxel {
    [10_000 + scan as u16, 20_000 + taxel, 30_000 + (scan as u16) * 2]
}

/// `scans` scans at 100 Hz, frames 100 µs apart, from t = 1700000000 s.
fn log_lines(scans: u64) -> Vec<String> {
    let l = XelaCanLayout { taxels: 16, ..XelaCanLayout::default() };
    let mut lines = vec![candump_line(1_700_000_000_000_000, "can0", &l.start_command())];
    for s in 0..scans {
        for t in 0..16u16 {
            let t_us = 1_700_000_000_000_000 + 1000 + s * 10_000 + u64::from(t) * 100;
            lines.push(candump_line(t_us, "can0", &l.taxel_frame(t, value(s, t), true)));
        }
    }
    lines
}

fn decode_log(lines: &[String]) -> (Vec<TactileSample>, DecoderCounters, u64) {
    let text = lines.join("\n") + "\n";
    let mut d = CanLogDecoder::new(text.as_bytes(), &can_cfg(), None).unwrap();
    let samples: Vec<_> = d.by_ref().collect();
    (samples, d.counters(), d.bad_lines())
}

#[test]
fn a_candump_line_has_the_can_utils_format() {
    let f = CanFrame::standard(0x710, &[0, 0x12, 0x34, 0x56, 0x78, 0x9A, 0xBC, 0]).unwrap();
    assert_eq!(
        candump_line(1_700_000_000_123_456, "can0", &f),
        "(1700000000.123456) can0 710#00123456789ABC00"
    );
    let e = CanFrame::new(0x18FF_0001, true, &[]).unwrap();
    assert_eq!(candump_line(5, "vcan0", &e), "(0.000005) vcan0 18FF0001#");
}

#[test]
fn a_clean_log_gives_every_scan_with_log_times() {
    let (samples, counters, bad) = decode_log(&log_lines(20));
    assert_eq!(samples.len(), 20);
    assert_eq!(bad, 0);
    for (s, sample) in samples.iter().enumerate() {
        let s = s as u64;
        assert_eq!(sample.raw, (0..16).map(|t| value(s, t)).collect::<Vec<_>>(), "every taxel of the patch");
        assert_eq!(sample.sequence, s);
        // Relative to the first record (the start command), at the scan's last frame.
        assert_eq!(sample.t, TimeNs((1000 + s * 10_000 + 1500) * 1000));
    }
    assert_eq!(counters.frames, 320);
    assert_eq!(counters.incomplete_scans, 0);
}

#[test]
fn a_damaged_log_loses_only_the_damaged_scans() {
    let mut lines = log_lines(10);
    lines[1 + 16 * 2 + 3] = "(1700000000.0abc) can0 713#00".into(); // bad timestamp: scan 2 loses a frame
    lines.insert(1 + 16 * 5, "garbage that is not candump".into());
    lines.swap(1 + 16 * 7 + 2, 1 + 16 * 7 + 9); // reordered inside scan 7 (times swap too)
    lines.remove(1 + 16 * 8 + 15); // scan 8 is truncated
    lines.truncate(lines.len() - 4); // the capture stopped inside scan 9
    let (samples, counters, bad) = decode_log(&lines);
    let seqs: Vec<u64> = samples.iter().map(|s| s.sequence).collect();
    assert_eq!(seqs, [0, 1, 3, 4, 5, 6, 7], "scans 2 and 8 dropped, 9 unfinished");
    assert_eq!(bad, 2);
    assert_eq!(counters.incomplete_scans, 2);
    let t: Vec<TimeNs> = samples.iter().map(|s| s.t).collect();
    assert!(t.windows(2).all(|w| w[0] <= w[1]), "times never decrease");
}

#[test]
fn other_interfaces_are_skipped_when_one_is_named() {
    let mut lines = log_lines(3);
    for l in lines.iter_mut().skip(17) {
        *l = l.replace(" can0 ", " can1 ");
    }
    let text = lines.join("\n");
    let d = CanLogDecoder::new(text.as_bytes(), &can_cfg(), Some("can0".into())).unwrap();
    assert_eq!(d.count(), 1);
    let d = CanLogDecoder::new(text.as_bytes(), &can_cfg(), None).unwrap();
    assert_eq!(d.count(), 3);
}

mod arbitrary {
    //! Arbitrary and damaged logs: no panic, bounded memory, and only
    //! whole scans with non-decreasing times come out.

    use proptest::prelude::*;

    use super::*;

    /// A line of a log: a plausible frame (maybe of the board) as
    /// `candump -l` or candump's console output prints it, or junk bytes.
    fn arb_line() -> impl Strategy<Value = Vec<u8>> {
        prop_oneof![
            3 => (0x700u32..0x720, proptest::collection::vec(any::<u8>(), 0..=8), 0u64..20_000_000)
                .prop_map(|(id, data, t_us)| {
                    let frame = CanFrame::standard(id, &data).expect("a standard id and <= 8 bytes");
                    candump_line(1_700_000_000_000_000 + t_us, "can0", &frame).into_bytes()
                }),
            2 => (0x700u32..0x720, proptest::collection::vec(any::<u8>(), 0..=8), proptest::option::of(0u64..20_000_000))
                .prop_map(|(id, data, t_us)| {
                    crate::can::candump::plain::format_plain_line(t_us, "can0", id, false, &data).into_bytes()
                }),
            1 => proptest::collection::vec(any::<u8>(), 0..120),
        ]
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(
            std::env::var("PROPTEST_CASES").ok().and_then(|s| s.parse().ok()).unwrap_or(256)
        ))]

        /// Logs of frames in any order, junk lines (invalid UTF-8 too) and
        /// random byte damage.
        #[test]
        fn arbitrary_candump_logs_never_panic(
            lines in proptest::collection::vec(arb_line(), 0..300),
            damage in proptest::collection::vec((any::<usize>(), any::<u8>()), 0..20),
        ) {
            let mut text = lines.join(&b'\n');
            for (at, byte) in damage {
                if !text.is_empty() {
                    let k = at % text.len();
                    text[k] = byte;
                }
            }
            let mut d = CanLogDecoder::new(text.as_slice(), &can_cfg(), None).unwrap();
            let mut last = TimeNs::ZERO;
            let mut n = 0u64;
            for sample in d.by_ref() {
                prop_assert!(sample.t >= last);
                last = sample.t;
                n += 1;
            }
            prop_assert!(d.bad_lines() <= d.lines());
            prop_assert!(n * 16 <= d.counters().frames, "{} scans from {} frames", n, d.counters().frames);
        }
    }
}

#[test]
fn console_output_decodes_with_and_without_times() {
    let l = XelaCanLayout { taxels: 16, ..XelaCanLayout::default() };
    let plain = |t_us: Option<u64>, f: &CanFrame| {
        crate::can::candump::plain::format_plain_line(t_us, "can0", f.id, f.extended, f.data())
    };
    for times in [None, Some(false), Some(true)] {
        let mut lines = Vec::new();
        for s in 0..5 {
            for t in 0..16u16 {
                let f = l.taxel_frame(t, value(s, t), true);
                // -t z: since the first frame; -t d: since the previous one.
                let t_us = times.map(|deltas| if deltas { 100 } else { s * 10_000 + u64::from(t) * 100 });
                lines.push(plain(t_us, &f));
            }
        }
        let text = lines.join("\n");
        let d =
            CanLogDecoder::new(text.as_bytes(), &can_cfg(), None).unwrap().with_deltas(times == Some(true));
        let samples: Vec<_> = d.collect();
        assert_eq!(samples.len(), 5, "{times:?}");
        for (s, sample) in samples.iter().enumerate() {
            assert_eq!(sample.raw, (0..16).map(|t| value(s as u64, t)).collect::<Vec<_>>());
        }
        match times {
            // Log order, spaced as if at rate_hz (100 Hz, 16 frames a scan).
            None => assert_eq!(samples[1].t.0 - samples[0].t.0, 10_000_000),
            Some(false) => assert_eq!(samples[1].t, TimeNs((10_000 + 1500) * 1000)),
            Some(true) => assert_eq!(samples[1].t, TimeNs(32 * 100 * 1000), "every gap added, the first too"),
        }
    }
}
