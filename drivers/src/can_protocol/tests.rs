//! The CAN scan assembler on frame sequences: clean, reordered, truncated,
//! corrupted, foreign ids, and arbitrary frames (proptest).

use proptest::prelude::*;

use super::*;

fn layout(taxels: u16) -> XelaCanLayout {
    XelaCanLayout { taxels, ..XelaCanLayout::default() }
}

fn value(scan: u64, taxel: u16) -> RawTaxel {
    let b = (scan as u16).wrapping_mul(31).wrapping_add(taxel * 3);
    [30_000 + b, 20_000 + b, 40_000 + b]
}

/// Scan period of the fixtures (ns): 100 Hz; taxel frames 100 us apart.
const PERIOD_NS: u64 = 10_000_000;

fn assembler(l: XelaCanLayout) -> CanScanAssembler {
    CanScanAssembler::new(l, CanScanAssembler::span_for_rate(100.0))
}

/// The frames of `scans` scans, in taxel order, with their receive times.
fn frames(l: &XelaCanLayout, scans: u64) -> Vec<(TimeNs, CanFrame)> {
    (0..scans)
        .flat_map(|s| {
            (0..l.taxels).map(move |t| {
                (TimeNs(s * PERIOD_NS + u64::from(t) * 100_000), l.taxel_frame(t, value(s, t), true))
            })
        })
        .collect()
}

fn assemble(a: &mut CanScanAssembler, frames: &[(TimeNs, CanFrame)]) -> Vec<CanScan> {
    frames.iter().filter_map(|(t, f)| a.push(*t, f)).collect()
}

#[test]
fn the_start_command_and_ids_follow_the_xela_layout() {
    let l = XelaCanLayout::default();
    let start = l.start_command();
    assert_eq!((start.id, start.data()), (0x201, &[7u8, 0][..]));
    let f = l.taxel_frame(3, [0x1234, 0x5678, 0x9ABC], true);
    assert_eq!(f.id, 0x713);
    assert_eq!(f.data(), &[0, 0x12, 0x34, 0x56, 0x78, 0x9A, 0xBC, 0]);
    assert_eq!(l.taxel_of(&f), Some(3));
    assert_eq!(l.taxel_of(&CanFrame::standard(0x720, &[0; 8]).unwrap()), None, "beyond 16 taxels");
    assert_eq!(l.taxel_of(&CanFrame::new(0x713, true, &[0; 8]).unwrap()), None, "extended id");
    assert!(XelaCanLayout { taxel_base_id: 0x7F8, ..l }.validate().is_err());
    assert!(XelaCanLayout { start_base_id: 0x800, ..l }.validate().is_err());
    assert!(layout(0).validate().is_err());
    assert!(CanFrame::standard(0x800, &[]).is_none() && CanFrame::standard(1, &[0; 9]).is_none());
}

#[test]
fn a_clean_sequence_gives_one_scan_per_round_of_taxels() {
    let l = layout(16);
    let mut a = assembler(l);
    let scans = assemble(&mut a, &frames(&l, 5));
    assert_eq!(scans.len(), 5);
    for (s, scan) in scans.iter().enumerate() {
        assert_eq!(scan.sequence, s as u64);
        assert_eq!(scan.t, TimeNs(s as u64 * PERIOD_NS + 15 * 100_000), "time of the completing frame");
        let expected: Vec<_> = (0..16).map(|t| Some(value(s as u64, t))).collect();
        assert_eq!(scan.taxels, expected);
    }
    assert_eq!(a.counters(), DecoderCounters { frames: 80, ..DecoderCounters::default() });
}

#[test]
fn frames_reordered_within_a_scan_still_assemble() {
    let l = layout(4);
    let mut fs = frames(&l, 2);
    fs.swap(0, 3);
    fs.swap(5, 6);
    let mut a = assembler(l);
    let scans = assemble(&mut a, &fs);
    assert_eq!(scans.len(), 2);
    assert_eq!(scans[0].taxels[0], Some(value(0, 0)));
    assert_eq!(a.counters().incomplete_scans, 0);
}

#[test]
fn a_lost_frame_drops_its_scan_without_emitting_it_half_filled() {
    let l = layout(4);
    let mut fs = frames(&l, 3);
    fs.remove(5); // scan 1, taxel 1
    let mut a = assembler(l);
    let scans = assemble(&mut a, &fs);
    let seqs: Vec<_> = scans.iter().map(|s| s.sequence).collect();
    assert_eq!(seqs, [0, 2], "scan 1 is dropped, its number skipped");
    assert_eq!(a.counters().incomplete_scans, 1);
    assert!(scans.iter().all(|s| s.taxels.iter().all(Option::is_some)));
}

#[test]
fn a_truncated_capture_leaves_the_last_scan_pending() {
    let l = layout(4);
    let fs = frames(&l, 3);
    let mut a = assembler(l);
    assert_eq!(assemble(&mut a, &fs[..10]).len(), 2);
    assert_eq!(a.pending(), 2);
}

#[test]
fn invalid_and_short_samples_are_counted_and_marked() {
    let l = layout(3);
    let mut fs = frames(&l, 2);
    fs[1].1 = l.taxel_frame(1, [1, 2, 3], false);
    fs[4].1 = CanFrame::standard(0x711, &[0, 1, 2]).unwrap(); // too short for x, y, z
    let mut a = assembler(l);
    let scans = assemble(&mut a, &fs);
    assert_eq!(scans.len(), 2);
    assert_eq!(scans[0].taxels[1], None);
    assert_eq!(scans[1].taxels[1], None);
    assert_eq!(a.counters().invalid_samples, 2);
    // Status bytes below 250 are valid.
    let f = CanFrame::standard(l.taxel_base_id, &[249, 0, 9, 0, 9, 0, 9, 0]).unwrap();
    let mut a = assembler(layout(1));
    assert_eq!(a.push(TimeNs(0), &f).unwrap().taxels, vec![Some([9, 9, 9])]);
}

#[test]
fn foreign_frames_are_ignored() {
    let l = layout(2);
    let mut fs = frames(&l, 2);
    fs.insert(1, (fs[0].0, CanFrame::standard(0x300, &[1, 2, 3]).unwrap())); // the hand's set-point
    fs.insert(3, (fs[2].0, l.start_command()));
    let mut a = assembler(l);
    assert_eq!(assemble(&mut a, &fs).len(), 2);
    assert_eq!(a.counters().frames, 4);
}

#[test]
fn frames_of_two_scans_are_never_mixed() {
    let l = layout(3);
    let fs = frames(&l, 2);
    // Scan 0 lost its last frame, scan 1 its first two: 0a 0b 1c would
    // complete a scan by taxel count alone; the time span keeps them apart.
    let mut a = assembler(l);
    assert!(assemble(&mut a, &[fs[0], fs[1], fs[5]]).is_empty());
    assert_eq!(a.counters().incomplete_scans, 1);
    // Scan 1's first frame overtakes scan 0's last: 0a 0b 1a 0c 1b 1c.
    // Every switch between the two scans drops the partial one.
    let mut a = assembler(l);
    let scans = assemble(&mut a, &[fs[0], fs[1], fs[3], fs[2], fs[4], fs[5]]);
    assert!(scans.is_empty(), "{scans:?}");
    assert_eq!(a.counters().incomplete_scans, 3);
}

fn arb_frame() -> impl Strategy<Value = CanFrame> {
    (0x700u32..0x730, any::<bool>(), proptest::collection::vec(any::<u8>(), 0..=8))
        .prop_map(|(id, ext, data)| CanFrame::new(id, ext, &data).unwrap())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(
        std::env::var("PROPTEST_CASES").ok().and_then(|s| s.parse().ok()).unwrap_or(256)
    ))]

    /// Arbitrary frames: no panic, every emitted scan is whole, counters add up.
    #[test]
    fn arbitrary_frames_never_panic_nor_emit_partial_scans(
        fs in proptest::collection::vec(arb_frame(), 0..600), taxels in 1u16..40,
    ) {
        let l = layout(taxels);
        let mut a = assembler(l);
        let mut emitted = 0u64;
        for (i, f) in fs.iter().enumerate() {
            if let Some(scan) = a.push(TimeNs(i as u64 * 100_000), f) {
                prop_assert_eq!(scan.taxels.len(), usize::from(taxels));
                emitted += 1;
            }
            prop_assert!(a.pending() < usize::from(taxels));
        }
        let c = a.counters();
        let ours = fs.iter().filter(|f| l.taxel_of(f).is_some()).count() as u64;
        prop_assert_eq!(c.frames, ours);
        prop_assert!(emitted * u64::from(taxels) <= ours);
    }

    /// Clean scans with some frames dropped: every scan that kept all its
    /// frames comes out with its own values.
    #[test]
    fn dropped_frames_only_cost_their_scans(drop in proptest::collection::vec(any::<bool>(), 8 * 6)) {
        let l = layout(8);
        let all = frames(&l, 6);
        let kept: Vec<_> = all.iter().zip(&drop).filter(|(_, d)| !**d).map(|(f, _)| *f).collect();
        let mut a = assembler(l);
        let scans = assemble(&mut a, &kept);
        for scan in &scans {
            // Values identify their scan: no mixing of two scans' frames.
            let s = (0..6u64).find(|&s| scan.taxels[0] == Some(value(s, 0))).expect("a known scan");
            for t in 0..8u16 {
                prop_assert_eq!(scan.taxels[usize::from(t)], Some(value(s, t)));
            }
        }
        let whole = drop.chunks(8).filter(|c| c.iter().all(|d| !d)).count();
        prop_assert!(scans.len() <= whole);
    }
}
