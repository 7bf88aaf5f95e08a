//! Decoding serial captures, including damaged ones.

use slidetrack_core::RawTaxel;

use super::*;
use crate::serial::protocol::ModuleFrame;

#[test]
fn a_serial_capture_decodes_with_times_from_the_scan_counter() {
    let cfg = SerialTactileConfig::default();
    let mut bytes = vec![0x13, 0x37, 0xA5]; // the capture started mid-frame
    for s in 0..50u16 {
        if s == 20 {
            continue; // a lost scan
        }
        for m in 0..3u8 {
            let taxels: Vec<RawTaxel> = (0..16).map(|t| [u16::from(m), s, t]).collect();
            ModuleFrame::new(m, s + 100, &taxels).unwrap().encode_into(&mut bytes);
        }
    }
    bytes.extend_from_slice(&[0xA5, 0x5A, 0x00]); // and ended mid-frame
    let mut d = SerialCaptureDecoder::new(bytes.as_slice(), &cfg, 1000.0);
    let samples: Vec<_> = d.by_ref().collect();
    assert_eq!(samples.len(), 49);
    // Three 4x4 modules (the default sensors), every taxel.
    let expected: Vec<RawTaxel> = (0..3).flat_map(|m| (0..16).map(move |t| [m, 0, t])).collect();
    assert_eq!(samples[0].raw, expected);
    assert_eq!(samples[0].sequence, 100);
    assert_eq!(samples[20].sequence, 121);
    assert_eq!(samples[20].t, TimeNs(21_000_000), "1 kHz from the first scan, across the lost one");
    let c = d.counters();
    assert_eq!((c.resyncs, c.gaps, c.frames), (1, 3, 147));
    assert_eq!(d.trailing_bytes(), 3);
    assert_eq!(d.bytes(), bytes.len() as u64);
}

mod arbitrary {
    //! Arbitrary and damaged captures: no panic, bounded memory, and only
    //! scans with non-decreasing times come out.

    use proptest::prelude::*;

    use super::*;

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(
            std::env::var("PROPTEST_CASES").ok().and_then(|s| s.parse().ok()).unwrap_or(256)
        ))]

        /// Raw captures of arbitrary bytes with valid frames spliced in.
        #[test]
        fn arbitrary_serial_captures_never_panic(
            junk in proptest::collection::vec(any::<u8>(), 0..6000),
            frames in proptest::collection::vec((0u8..4, any::<u16>(), 1usize..20, any::<usize>()), 0..40),
        ) {
            let mut bytes = junk;
            for (module, sequence, taxels, at) in frames {
                let values: Vec<RawTaxel> = (0..taxels).map(|t| [t as u16, sequence, 7]).collect();
                let f = ModuleFrame::new(module, sequence, &values).expect("1..=64 taxels").encode();
                let at = if bytes.is_empty() { 0 } else { at % bytes.len() };
                bytes.splice(at..at, f);
            }
            let mut d = SerialCaptureDecoder::new(bytes.as_slice(), &SerialTactileConfig::default(), 1000.0);
            let mut last = TimeNs::ZERO;
            for sample in d.by_ref() {
                prop_assert!(sample.t >= last);
                last = sample.t;
            }
            prop_assert_eq!(d.bytes(), bytes.len() as u64);
            prop_assert!(d.trailing_bytes() <= crate::serial::protocol::DECODER_CAPACITY);
            prop_assert!(d.error().is_none());
        }
    }
}
