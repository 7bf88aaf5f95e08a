//! Layout resolution, payloads, both scan modes, round trips through the
//! encoder, and arbitrary frames (proptest, fixed seed).

use proptest::prelude::*;
use slidetrack_core::{RawTaxel, TimeNs};

use super::*;
use crate::can::config::CanTactileConfig;

fn sensor(name: &str, module: u32, rows: u32, cols: u32) -> HwSensor {
    HwSensor {
        name: name.into(),
        module,
        finger: "thumb".into(),
        model: "test".into(),
        rows,
        cols,
        taxel_positions_mm: None,
    }
}

/// A 2x3 patch and a 1x2 strip.
fn sensors() -> Vec<HwSensor> {
    vec![sensor("patch", 0, 2, 3), sensor("strip", 1, 1, 2)]
}

fn cfg(map: Vec<MapEntry>) -> CanTactileConfig {
    CanTactileConfig { sensors: sensors(), map, ..CanTactileConfig::default() }
}

fn ids(layout: &ResolvedLayout) -> Vec<u32> {
    layout.slots.iter().map(|((id, _), _)| *id).collect()
}

fn entry(sensor: &str) -> MapEntry {
    MapEntry { sensor: sensor.into(), ..MapEntry::default() }
}

fn value(scan: u16, slot: usize) -> RawTaxel {
    [scan, 1000 + slot as u16, 60_000 - slot as u16]
}

fn scan_values(scan: u16, n: usize) -> Vec<RawTaxel> {
    (0..n).map(|k| value(scan, k)).collect()
}

#[test]
fn the_legacy_layout_puts_taxel_t_of_module_m_at_base_plus_m_times_per_module_plus_t() {
    let layout = cfg(vec![]).layout().unwrap();
    assert_eq!(ids(&layout), [0x710, 0x711, 0x712, 0x713, 0x714, 0x715, 0x720, 0x721]);
    assert_eq!(layout.start.len(), 1, "the legacy start command");
    assert_eq!((layout.start[0].0.id, layout.start[0].0.data()), (0x201, &[7u8, 0][..]));
    assert!(layout.stop.is_empty());
    assert_eq!(layout.payload, PayloadFormat::default());
    assert_eq!(layout.payload.valid, None, "no validity byte unless configured");
}

#[test]
fn a_map_expresses_gapped_row_column_and_single_ids() {
    let patch =
        MapEntry { base_id: Some(0x300), row_stride: Some(0x10), col_stride: Some(2), ..entry("patch") };
    let strip0 = MapEntry { id: Some(0x7F0), taxel: Some(1), ..entry("strip") };
    let strip1 = MapEntry { first_id: Some(0x100), count: Some(1), ..entry("strip") };
    let layout = cfg(vec![patch, strip0, strip1]).layout().unwrap();
    // Row-major: (0,0) (0,1) (0,2) (1,0) (1,1) (1,2), then the strip.
    assert_eq!(ids(&layout), [0x300, 0x302, 0x304, 0x310, 0x312, 0x314, 0x100, 0x7F0]);
    assert!(layout.start.is_empty(), "no legacy start command with a map");
    let stepped = MapEntry { first_id: Some(0x200), id_step: Some(4), ..entry("patch") };
    let rest = MapEntry { first_id: Some(0x600), ..entry("strip") };
    assert_eq!(ids(&cfg(vec![stepped, rest]).layout().unwrap())[..3], [0x200, 0x204, 0x208]);
}

#[test]
fn bad_maps_name_the_entry_and_the_fault() {
    let whole = |s: &str, id| MapEntry { first_id: Some(id), ..entry(s) };
    let err = |map: Vec<MapEntry>| cfg(map).layout().unwrap_err().to_string();
    assert_eq!(
        err(vec![whole("patch", 0x300)]),
        "hw.tactile.map maps no CAN id to taxel 0 of sensor `strip` (every taxel needs one)"
    );
    assert_eq!(
        err(vec![whole("patch", 0x300), whole("strip", 0x305)]),
        "CAN id 0x305 is given twice: by hw.tactile.map[0] (taxel 5) and by hw.tactile.map[1] (taxel 0)"
    );
    let e = err(vec![whole("thumb", 0x300)]);
    assert_eq!(e, "hw.tactile.map[0]: sensor `thumb` is not in hw.tactile.sensors");
    let e = err(vec![MapEntry { id: Some(1), first_id: Some(2), ..entry("patch") }]);
    assert!(e.starts_with("hw.tactile.map[0]: give exactly one of `id`"), "{e}");
    let e = err(vec![whole("patch", 0x300), MapEntry { id: Some(0x400), taxel: Some(2), ..entry("strip") }]);
    assert_eq!(e, "hw.tactile.map[1]: taxel 2 is beyond sensor `strip`'s 2 taxels");
    let e = err(vec![MapEntry { first_id: Some(0x300), taxel: Some(1), ..entry("patch") }]);
    assert_eq!(e, "hw.tactile.map[0]: `taxel` does not belong to this form of entry");
    let e = err(vec![whole("patch", 0x7FC), whole("strip", 0x600)]);
    assert_eq!(e, "hw.tactile.map[0] (taxel 4) = 0x800 is beyond the 11-bit CAN id range");
    let twice = vec![
        whole("patch", 0x300),
        whole("strip", 0x400),
        MapEntry { id: Some(0x500), taxel: Some(0), ..entry("strip") },
    ];
    assert_eq!(err(twice), "taxel 0 of sensor `strip` is mapped twice (ids 0x400 and 0x500)");
    let mut c = cfg(vec![whole("patch", 0x300), whole("strip", 0x400)]);
    c.stop = Some(CommandFrame { id: 0x401, extended: false, data: vec![0] });
    assert_eq!(
        c.layout().unwrap_err().to_string(),
        "CAN id 0x401 is given twice: by hw.tactile.map[1] (taxel 1) and by hw.tactile.stop"
    );
    c.stop = Some(CommandFrame { id: 0x10, extended: false, data: vec![0; 9] });
    assert!(c.layout().unwrap_err().to_string().starts_with("hw.tactile.stop: id 0x10 with 9 data bytes"));
}

#[test]
fn payload_formats_decode_what_they_encode_and_refuse_overlaps() {
    let le = PayloadFormat { byte_order: ByteOrder::Little, x: 0, y: 2, z: 4, valid: None };
    assert_eq!(le.encode([0x0102, 0x0304, 0x0506]), [2, 1, 4, 3, 6, 5]);
    assert_eq!(le.decode(&[2, 1, 4, 3, 6, 5, 9, 9]), Payload::Valid([0x0102, 0x0304, 0x0506]));
    assert_eq!(le.decode(&[2, 1, 4, 3, 6]), Payload::TooShort);
    let be = PayloadFormat::default();
    assert_eq!(
        be.decode(&[250, 0, 1, 0, 2, 0, 3]),
        Payload::Valid([1, 2, 3]),
        "byte 0 is not checked by default"
    );
    let checked = PayloadFormat { valid: Some(ValidityByte { byte: 0, below: 250 }), ..be };
    assert_eq!(checked.decode(&[250, 0, 1, 0, 2, 0, 3]), Payload::Invalid);
    assert_eq!(checked.decode(&[249, 0, 1, 0, 2, 0, 3]), Payload::Valid([1, 2, 3]));
    assert!(checked.validate().is_ok());
    let overlap = PayloadFormat { y: 2, ..be };
    assert_eq!(overlap.validate().unwrap_err().to_string(), "hw.tactile.payload.y and .x share byte 2");
    let beyond = PayloadFormat { z: 7, ..be };
    assert!(beyond.validate().unwrap_err().to_string().contains("payload.z = 7 ends beyond the 8 bytes"));
    let on_status = PayloadFormat { valid: Some(ValidityByte { byte: 1, below: 1 }), ..be };
    assert!(on_status.validate().is_err(), "the validity byte may not be a value byte");
}

#[test]
fn complete_mode_emits_whole_scans_and_counts_broken_ones_without_any_timing_rule() {
    let layout = cfg(vec![]).layout().unwrap();
    let n = layout.slots.len();
    let frames = |s: u16| layout.encode_scan(&scan_values(s, n));
    let mut d = CanLayoutDecoder::new(layout.clone(), 100.0);
    let mut out = Vec::new();
    // Scan 0 whole with frames a second apart (no 5 ms gap rule); scan 1
    // loses its last frame; scan 2 loses its first; scan 3 whole.
    for (k, f) in frames(0).iter().enumerate() {
        out.extend(d.push(TimeNs(k as u64 * 1_000_000_000), f));
    }
    let mut t = TimeNs(100_000_000_000);
    let mut feed = |d: &mut CanLayoutDecoder, fs: &[CanFrame], out: &mut Vec<LayoutScan>| {
        for f in fs {
            t.0 += 1000;
            out.extend(d.push(t, f));
        }
    };
    feed(&mut d, &frames(1)[..n - 1], &mut out);
    feed(&mut d, &frames(2)[1..], &mut out);
    feed(&mut d, &frames(3), &mut out);
    let values: Vec<(u64, u16)> = out.iter().map(|s| (s.sequence, s.taxels[0][0])).collect();
    assert_eq!(values, [(0, 0), (3, 3)]);
    assert_eq!(out[1].taxels, scan_values(3, n), "every taxel of the scan");
    assert_eq!(out[0].t, TimeNs((n as u64 - 1) * 1_000_000_000), "the time of the completing frame");
    let c = d.counters();
    assert_eq!((c.frames, c.incomplete_scans, c.invalid_samples), (4 * n as u64 - 2, 2, 0));
    // Frames of other ids are ignored altogether.
    let other = CanFrame::standard(0x123, &[1, 2, 3, 4, 5, 6, 7, 8]).unwrap();
    assert_eq!(d.push(t, &other), None);
    assert_eq!(d.counters(), c);
}

#[test]
fn a_scan_start_frame_ends_an_unfinished_scan() {
    let mut c = cfg(vec![]);
    c.scan_start_id = Some(0x7FF);
    let layout = c.layout().unwrap();
    let n = layout.slots.len();
    let frames = layout.encode_scan(&scan_values(5, n));
    let mut d = CanLayoutDecoder::new(layout, 100.0);
    let start = CanFrame::standard(0x7FF, &[]).unwrap();
    for f in &frames[1..3] {
        assert_eq!(d.push(TimeNs(1), f), None);
    }
    assert_eq!(d.push(TimeNs(2), &start), None);
    assert_eq!(d.counters().incomplete_scans, 1);
    let done: Vec<_> = frames.iter().filter_map(|f| d.push(TimeNs(3), f)).collect();
    assert_eq!(done.len(), 1);
}

#[test]
fn latest_mode_emits_the_newest_values_at_the_rate_once_every_taxel_was_seen() {
    let mut c = cfg(vec![]);
    c.scan_mode = ScanMode::Latest;
    let layout = c.layout().unwrap();
    let n = layout.slots.len();
    let mut d = CanLayoutDecoder::new(layout.clone(), 100.0); // every 10 ms
    let ms = |m: u64| TimeNs(m * 1_000_000);
    let first = layout.encode_scan(&scan_values(1, n));
    for f in &first[..n - 1] {
        assert_eq!(d.push(ms(0), f), None, "not every taxel seen yet");
    }
    assert_eq!(d.poll(ms(50)), None);
    let a = d.push(ms(51), &first[n - 1]).expect("every taxel seen: emitted at once");
    assert_eq!((a.t, a.sequence, a.taxels.clone()), (ms(51), 0, scan_values(1, n)));
    // Only taxel 2 updates; the next emission is due 10 ms later.
    let update = layout.encode_scan(&scan_values(9, n))[2];
    assert_eq!(d.push(ms(55), &update), None);
    assert_eq!(d.poll(ms(60)), None);
    let b = d.poll(ms(61)).expect("due");
    assert_eq!(b.sequence, 1);
    assert_eq!(b.taxels[2], value(9, 2));
    assert_eq!(b.taxels[3], value(1, 3), "the others keep their latest value");
    // Late by several periods: one scan, not a burst.
    assert!(d.poll(ms(200)).is_some());
    assert_eq!(d.poll(ms(201)), None);
}

#[test]
fn the_legacy_and_a_map_layout_round_trip_through_the_encoder() {
    let patch =
        MapEntry { base_id: Some(0x300), row_stride: Some(0x20), col_stride: Some(3), ..entry("patch") };
    let strip =
        MapEntry { first_id: Some(0x1ABC_0000), extended: true, id_step: Some(0x100), ..entry("strip") };
    let mut map = cfg(vec![patch, strip]);
    map.payload = PayloadFormat { byte_order: ByteOrder::Little, x: 6, y: 0, z: 3, valid: None };
    for c in [cfg(vec![]), map] {
        let layout = c.layout().unwrap();
        let n = layout.slots.len();
        let mut d = CanLayoutDecoder::new(layout.clone(), 100.0);
        for s in 0..5 {
            let frames = layout.encode_scan(&scan_values(s, n));
            assert_eq!(frames.len(), n);
            let scans: Vec<_> = frames.iter().filter_map(|f| d.push(TimeNs(u64::from(s)), f)).collect();
            assert_eq!(scans.len(), 1);
            assert_eq!(scans[0].taxels, scan_values(s, n));
        }
        assert_eq!(d.counters().incomplete_scans, 0);
    }
}

/// An arbitrary layout over the two sensors: legacy, or a map of ranges
/// (ids may collide: resolution then fails, which is fine), with any
/// payload, mode and validity byte.
fn arbitrary_cfg() -> impl Strategy<Value = CanTactileConfig> {
    (any::<bool>(), 0u32..0x7F0, 0u32..0x7F0, 1u32..5, 0u8..7, 0u8..7, 0u8..7, any::<bool>(), any::<bool>())
        .prop_map(|(legacy, a, b, step, x, y, z, little, latest)| {
            let map = if legacy {
                vec![]
            } else {
                vec![
                    MapEntry { first_id: Some(a), id_step: Some(step), ..entry("patch") },
                    MapEntry { first_id: Some(b), ..entry("strip") },
                ]
            };
            let byte_order = if little { ByteOrder::Little } else { ByteOrder::Big };
            let valid = (x == 0).then_some(ValidityByte { byte: 7, below: 200 });
            CanTactileConfig {
                payload: PayloadFormat { byte_order, x, y, z, valid },
                scan_mode: if latest { ScanMode::Latest } else { ScanMode::Complete },
                ..cfg(map)
            }
        })
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: std::env::var("PROPTEST_CASES").ok().and_then(|s| s.parse().ok()).unwrap_or(256),
        rng_seed: proptest::test_runner::RngSeed::Fixed(
            std::env::var("SLIDETRACK_DAMAGE_SEED").ok().and_then(|s| s.parse().ok()).unwrap_or(1)
        ),
        failure_persistence: None,
        ..ProptestConfig::default()
    })]

    /// Arbitrary frames (ids near the mapped ones, any length and data,
    /// any times) into any layout that resolves: no panic, every scan
    /// whole, bounded state, counters consistent.
    #[test]
    fn arbitrary_frames_into_any_layout_never_panic(
        c in arbitrary_cfg(),
        frames in proptest::collection::vec(
            (0u32..0x800, any::<bool>(), proptest::collection::vec(any::<u8>(), 0..=8), 0u64..20_000_000),
            0..400,
        ),
    ) {
        let Ok(layout) = c.layout() else { return Ok(()) };
        let n = layout.slots.len();
        let mut d = CanLayoutDecoder::new(layout, c.rate_hz);
        let mut t = 0u64;
        let mut emitted = 0u64;
        for (id, extended, data, step) in frames {
            t += step;
            let Some(frame) = CanFrame::new(id, extended, &data) else { continue };
            let a = d.push(TimeNs(t), &frame);
            let b = d.poll(TimeNs(t));
            for scan in a.iter().chain(&b) {
                prop_assert_eq!(scan.taxels.len(), n);
                emitted += 1;
            }
            prop_assert!(d.pending() <= n);
        }
        let counters = d.counters();
        prop_assert!(counters.invalid_samples <= counters.frames);
        if c.scan_mode == ScanMode::Complete {
            prop_assert!(emitted * n as u64 <= counters.frames);
        }
    }

    /// Whole scans with frames other than the first dropped at random:
    /// complete mode never emits a scan mixing values of two scans. (The
    /// first taxel's frame marks a scan's start; when it is lost, nothing
    /// but a configured `scan_start_id` can tell the scans apart, see
    /// `docs/protocols.md`.)
    #[test]
    fn dropped_frames_never_mix_two_scans(mut drops in proptest::collection::vec(any::<bool>(), 8 * 30)) {
        for s in 0..30 {
            drops[s * 8] = false;
        }
        let layout = cfg(vec![]).layout().unwrap();
        let n = layout.slots.len();
        let mut d = CanLayoutDecoder::new(layout.clone(), 100.0);
        let mut whole = 0;
        for s in 0..30u16 {
            let kept: Vec<bool> = drops[usize::from(s) * n..(usize::from(s) + 1) * n].to_vec();
            whole += usize::from(kept.iter().all(|k| !k));
            for (f, drop) in layout.encode_scan(&scan_values(s, n)).iter().zip(kept) {
                if drop {
                    continue;
                }
                if let Some(scan) = d.push(TimeNs(u64::from(s)), f) {
                    prop_assert_eq!(scan.taxels, scan_values(s, n));
                }
            }
        }
        // Every scan is emitted whole or counted, but the last, which may still be pending.
        let last_pending = usize::from(drops[29 * 8..].iter().any(|x| *x));
        prop_assert_eq!(d.counters().incomplete_scans as usize + whole + last_pending, 30);
    }
}
