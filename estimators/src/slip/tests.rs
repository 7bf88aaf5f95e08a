//! The detector on synthetic load traces, and the metrics on hand-computed
//! cases. Each test names the bug it catches.

use super::*;

/// Refresh period of the xela-imanlab tactile values (s).
const DT_S: f64 = 0.1;
/// Peak load of the first grasp (counts).
const PEAK: f64 = 100_000.0;

fn detector(cfg: GraspDetectorConfig) -> GraspDetector {
    GraspDetector::new(cfg).expect("valid settings")
}

/// Feeds the scans and returns every reading.
fn run(d: &mut GraspDetector, scans: &[GraspScan]) -> Vec<GraspReading> {
    scans.iter().map(|s| d.update(*s)).collect()
}

/// Loads (counts) as scans every `DT_S`, from `t0_s`.
fn scans(t0_s: f64, loads: &[f64]) -> Vec<GraspScan> {
    loads.iter().enumerate().map(|(k, &l)| GraspScan::load(t0_s + k as f64 * DT_S, l)).collect()
}

fn states(readings: &[GraspReading]) -> Vec<GraspState> {
    readings.iter().map(|r| r.state).collect()
}

/// Entries into `state` in a sequence of readings.
fn entries(readings: &[GraspReading], state: GraspState) -> usize {
    readings.iter().filter(|r| r.state == state && r.changed).count()
}

/// Approach, grasp ramping up to `peak`, and a hold that dips to
/// `dip * peak` and comes back.
fn grasp_with_dip(peak: f64, dip: f64) -> Vec<f64> {
    let mut loads = vec![0.0, 10.0, -20.0];
    loads.extend([0.1, 0.3, 0.6, 0.9, 1.0, 0.95].map(|f| f * peak));
    loads.extend([0.7, 0.5, dip, dip, 0.45, 0.6, 0.8].map(|f| f * peak));
    loads
}

/// Catches a drop threshold above 0.3, or a ratio taken against anything but
/// the running peak (the contact level, the first held sample).
#[test]
fn a_hold_with_dips_to_0_3_of_its_peak_stays_held() {
    let mut d = detector(GraspDetectorConfig::default());
    let readings = run(&mut d, &scans(0.0, &grasp_with_dip(PEAK, 0.3)));
    assert_eq!(readings[2].state, GraspState::Idle);
    assert!(readings[3..].iter().all(|r| r.state == GraspState::Holding), "{:?}", states(&readings));
    let lowest = readings.iter().filter_map(|r| r.load_ratio).fold(f64::INFINITY, f64::min);
    assert!((lowest - 0.3).abs() < 1e-12, "{lowest}");
    assert_eq!(readings.last().map(|r| r.peak_load_counts), Some(Some(PEAK)));
}

/// Catches a drop decided late (a debounce, a moving average of the ratio)
/// or against the wrong comparison: the first scan under 0.1 is Dropped.
#[test]
fn a_fall_to_0_01_is_dropped_on_the_scan_that_crosses_the_threshold() {
    let mut loads = grasp_with_dip(PEAK, 0.5);
    loads.extend([0.6, 0.3, 0.11, 0.099, 0.06, 0.01, 0.0].map(|f| f * PEAK));
    let mut d = detector(GraspDetectorConfig::default());
    let readings = run(&mut d, &scans(0.0, &loads));
    let crossing = loads.iter().position(|&l| l == 0.099 * PEAK).expect("the crossing");
    assert_eq!(readings[crossing - 1].state, GraspState::Holding);
    assert_eq!(readings[crossing].state, GraspState::Dropped);
    assert!(readings[crossing].changed);
    // Dropped lasts while the load is at or above the contact level (6000
    // counts), then Idle.
    assert_eq!(readings[crossing + 1].state, GraspState::Dropped);
    assert_eq!(readings[crossing + 2].state, GraspState::Idle);
    assert_eq!(entries(&readings, GraspState::Dropped), 1);
}

/// A hold where the gripper first squeezes 3 mm shut, then opens 6 mm while
/// the load falls: 6 mm over its minimum but only 3 mm over where it began.
fn release_trace(open_by_m: f64) -> Vec<GraspScan> {
    let loads = [0.0, 0.5, 1.0, 1.0, 0.9, 0.9, 0.8, 0.3, 0.02, 0.0].map(|f| f * PEAK);
    let openings = [0.05, 0.05, 0.048, 0.047, 0.047, 0.047, 0.047 + open_by_m / 2.0, 0.047 + open_by_m];
    scans(0.0, &loads)
        .into_iter()
        .enumerate()
        .map(|(k, s)| s.with_opening(openings[k.min(openings.len() - 1)]))
        .collect()
}

/// Catches a release taken for a drop, and an opening measured from the
/// start of the hold instead of its minimum (which would read 3 mm: Dropped).
#[test]
fn opening_the_gripper_is_a_release_and_a_closed_gripper_a_drop() {
    let mut d = detector(GraspDetectorConfig::default());
    let readings = run(&mut d, &release_trace(0.006));
    assert_eq!(entries(&readings, GraspState::Released), 1, "{:?}", states(&readings));
    assert_eq!(entries(&readings, GraspState::Dropped), 0);
    let released = readings.iter().find(|r| r.state == GraspState::Released).expect("released");
    assert!((released.opening_growth_m.expect("opening") - 0.006).abs() < 1e-12);
    // The same fall with the gripper opening only 4 mm is a drop.
    let mut d = detector(GraspDetectorConfig::default());
    let readings = run(&mut d, &release_trace(0.004));
    assert_eq!(entries(&readings, GraspState::Dropped), 1, "{:?}", states(&readings));
    assert_eq!(entries(&readings, GraspState::Released), 0);
}

/// Catches a peak not reset at a re-grasp: the second, weaker grasp dips to
/// 0.06 of the first grasp's peak (a drop against it) but 0.4 of its own.
#[test]
fn a_regrasp_after_a_drop_holds_again_against_its_own_peak() {
    let mut loads = grasp_with_dip(PEAK, 0.5);
    loads.extend([0.01, 0.0, 0.0].map(|f| f * PEAK));
    let second = 0.15 * PEAK;
    loads.extend([0.5, 1.0, 0.8, 0.4, 0.4, 0.9].map(|f| f * second));
    let mut d = detector(GraspDetectorConfig::default());
    let readings = run(&mut d, &scans(0.0, &loads));
    assert_eq!(entries(&readings, GraspState::Dropped), 1, "{:?}", states(&readings));
    let regrasp = readings.iter().rposition(|r| r.state == GraspState::Idle).expect("idle") + 1;
    assert!(readings[regrasp..].iter().all(|r| r.state == GraspState::Holding && r.grasp == 2));
    assert_eq!(readings.last().and_then(|r| r.peak_load_counts), Some(second));
}

fn slip_cfg(enter_min_s: f64) -> GraspDetectorConfig {
    let slip = SlipHysteresis { enter_score: 1.0, exit_score: 0.5, enter_min_s };
    GraspDetectorConfig { slip: Some(slip), ..GraspDetectorConfig::default() }
}

/// A steady hold with the given slip scores, one per scan.
fn slip_scans(scores: &[f64]) -> Vec<GraspScan> {
    let loads: Vec<f64> = (0..scores.len()).map(|k| PEAK * (1.0 - 1e-4 * k as f64)).collect();
    scans(0.0, &loads).into_iter().zip(scores).map(|(s, &score)| s.with_slip(score)).collect()
}

/// Catches a single threshold (leaving Slipping below `enter_score`), which
/// chatters: the score crosses `enter` briefly, then oscillates around it
/// without falling under `exit` (one episode), then falls (it ends).
#[test]
fn slip_hysteresis_gives_one_episode_for_a_score_oscillating_between_the_thresholds() {
    let mut scores = vec![0.0, 0.1, 1.2, 0.8];
    for _ in 0..10 {
        scores.extend([1.1, 0.7, 0.9, 0.6]);
    }
    scores.extend([0.4, 0.2, 0.1]);
    let mut d = detector(slip_cfg(0.0));
    let readings = run(&mut d, &slip_scans(&scores));
    assert_eq!(entries(&readings, GraspState::Slipping), 1, "{:?}", states(&readings));
    let first = readings.iter().position(|r| r.state == GraspState::Slipping);
    assert_eq!(first, Some(2));
    assert_eq!(readings.last().map(|r| r.state), Some(GraspState::Holding));
    assert_eq!(readings[2].slip_enter_score, Some(1.0));
}

/// Catches a missing debounce: one scan above `enter` does not slip when
/// `enter_min_s` is 0.15 s; a score that stays above does, 0.2 s (two
/// refreshes at 10 Hz) after it rose.
#[test]
fn a_slip_shorter_than_enter_min_s_is_not_an_episode() {
    let scores = [0.0, 2.0, 0.8, 0.8, 2.0, 2.0, 2.0, 2.0, 0.0];
    let mut d = detector(slip_cfg(0.15));
    let readings = run(&mut d, &slip_scans(&scores));
    let got = states(&readings);
    assert_eq!(got[..6].iter().filter(|s| **s == GraspState::Slipping).count(), 0, "{got:?}");
    assert_eq!(got[6], GraspState::Slipping, "{got:?}");
    assert_eq!(entries(&readings, GraspState::Slipping), 1);
}

/// Catches deciding on repeated rows: with a 50 ms debounce the repeated
/// stream would count 50 ms of a value seen at one refresh and slip at
/// 0.05 s, staying Slipping at the next refresh (score between the
/// thresholds) where the deduplicated stream holds.
#[test]
fn repeated_rows_give_the_states_of_the_deduplicated_stream() {
    let scores = [0.0, 1.5, 0.8, 1.5, 1.5, 0.7, 0.2, 0.2];
    let mut loads: Vec<f64> = (0..scores.len()).map(|k| PEAK * (0.5 + 0.01 * k as f64)).collect();
    loads.extend([0.3, 0.01, 0.0].map(|f| f * PEAK));
    let refresh: Vec<GraspScan> = scans(0.0, &loads)
        .into_iter()
        .enumerate()
        .map(|(k, s)| s.with_slip(scores.get(k).copied().unwrap_or(0.0)))
        .collect();
    let mut d = detector(slip_cfg(0.05));
    let expected = run(&mut d, &refresh);
    let repeated: Vec<GraspScan> = refresh
        .iter()
        .flat_map(|s| (0..4).map(move |r| GraspScan { t_s: s.t_s + r as f64 * 0.025, ..*s }))
        .collect();
    let mut d = detector(slip_cfg(0.05));
    let got = run(&mut d, &repeated);
    for (k, want) in expected.iter().enumerate() {
        for (r, reading) in got[4 * k..4 * k + 4].iter().enumerate() {
            assert_eq!(reading.state, want.state, "refresh {k}, repeat {r}");
            assert_eq!(reading.fresh, r == 0);
            assert_eq!(reading.load_ratio, want.load_ratio);
        }
    }
    assert_eq!(entries(&got, GraspState::Slipping), 1);
    assert_eq!(entries(&got, GraspState::Dropped), 1);
}

/// Catches a non-finite value taken as data: an infinite load would become
/// the peak (every later ratio 0: a drop), a NaN opening would poison the
/// minimum, a NaN time the debounce.
#[test]
fn non_finite_inputs_keep_the_state_and_do_not_poison_later_decisions() {
    let mut d = detector(slip_cfg(0.0));
    let held = |t_s: f64| GraspScan::load(t_s, PEAK).with_slip(0.0).with_opening(0.05);
    assert_eq!(d.update(GraspScan::load(f64::NAN, f64::NAN)).state, GraspState::Idle);
    assert_eq!(d.update(held(0.0)).state, GraspState::Holding);
    for (k, bad) in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY].into_iter().enumerate() {
        let step = (k + 1) as f64;
        // A bad load and opening (the slip score changes, so the scan is fresh).
        let scan = GraspScan {
            t_s: 0.1 * step,
            load_counts: bad,
            slip_score: Some(0.01 * step),
            opening_m: Some(bad),
            releasing: false,
        };
        let r = d.update(scan);
        assert_eq!((r.state, r.fresh), (GraspState::Holding, true), "{bad}");
        assert_eq!((r.load_counts, r.load_ratio, r.opening_growth_m), (None, None, Some(0.0)));
        // A bad slip score.
        let r = d.update(GraspScan::load(0.1 * step + 0.05, PEAK * (1.0 - 0.01 * step)).with_slip(bad));
        assert_eq!((r.state, r.fresh, r.slip_score), (GraspState::Holding, true, None), "{bad}");
        // A bad time.
        let r = d.update(GraspScan { t_s: bad, ..held(0.0) });
        assert_eq!((r.state, r.fresh), (GraspState::Holding, false), "{bad}");
    }
    assert_eq!(d.update(held(0.5).with_slip(2.0)).state, GraspState::Slipping);
    assert_eq!(d.update(held(0.6).with_slip(f64::NAN)).state, GraspState::Slipping);
    let r = d.update(GraspScan::load(0.7, 0.5 * PEAK).with_slip(0.0));
    assert_eq!((r.state, r.load_ratio, r.peak_load_counts), (GraspState::Holding, Some(0.5), Some(PEAK)));
    let r = d.update(GraspScan::load(0.8, 0.01 * PEAK).with_opening(0.051));
    assert_eq!(
        (r.state, r.opening_growth_m.map(|g| (g - 0.001).abs() < 1e-12)),
        (GraspState::Dropped, Some(true))
    );
}

/// Catches settings accepted out of range, and the serde shape changing.
#[test]
fn settings_are_checked_and_read_back() {
    let cfg = GraspDetectorConfig::default();
    assert_eq!((cfg.contact_load_counts, cfg.drop_load_ratio, cfg.release_opening_m), (5000.0, 0.1, 0.005));
    let json = serde_json::to_string(&slip_cfg(0.1)).expect("json");
    let back: GraspDetectorConfig = serde_json::from_str(&json).expect("read back");
    assert_eq!(back, slip_cfg(0.1));
    let partial: GraspDetectorConfig =
        serde_json::from_str(r#"{"contact_load_counts": 800}"#).expect("partial");
    assert_eq!(partial, GraspDetectorConfig { contact_load_counts: 800.0, ..cfg });
    assert!(serde_json::from_str::<GraspDetectorConfig>(r#"{"drop_ratio": 0.2}"#).is_err());
    let inverted = SlipHysteresis { enter_score: 1.0, exit_score: 2.0, enter_min_s: 0.0 };
    for bad in [
        GraspDetectorConfig { drop_load_ratio: 1.0, ..cfg },
        GraspDetectorConfig { drop_load_ratio: f64::NAN, ..cfg },
        GraspDetectorConfig { contact_load_counts: 0.0, ..cfg },
        GraspDetectorConfig { release_opening_m: -0.001, ..cfg },
        GraspDetectorConfig { slip: Some(inverted), ..cfg },
    ] {
        assert!(matches!(GraspDetector::new(bad), Err(GraspError::InvalidConfig { .. })), "{bad:?}");
    }
    let reading = detector(cfg).update(GraspScan::load(0.0, PEAK));
    let logged = serde_json::to_value(reading).expect("json");
    assert_eq!(logged["state"], "holding");
    assert_eq!(GraspState::Holding.as_str(), "holding");
}

/// Catches a reference that takes the first fall below half the peak (the
/// dip that recovers) instead of the one that lasts.
#[test]
fn tactile_release_skips_a_dip_that_recovers_and_finds_the_real_fall() {
    let cfg = GraspDetectorConfig::default();
    let loads =
        [0.0, 3000.0, 50_000.0, 100_000.0, 40_000.0, 45_000.0, 80_000.0, 90_000.0, 30_000.0, 500.0, 0.0];
    let times: Vec<f64> = (0..loads.len()).map(|k| k as f64 * DT_S).collect();
    let release = tactile_release(&times, &loads, &cfg).expect("same lengths");
    // At sample 8 the load (30,000) is below half its level before (the
    // median of 50,000 .. 90,000 since the hold began: 65,000) and never
    // rises back: the collapse.
    assert_eq!(release, Some(times[8]));
    // Half the peak exactly counts as not released; ending above: no release.
    let recovered = [0.0, 100_000.0, 40_000.0, 50_000.0];
    assert_eq!(tactile_release(&times[..4], &recovered, &cfg), Ok(None));
    // No contact, no release; NaN samples are skipped.
    assert_eq!(tactile_release(&times[..3], &[0.0, 4000.0, 0.0], &cfg), Ok(None));
    let with_nan = [0.0, 100_000.0, f64::NAN, 1000.0];
    assert_eq!(tactile_release(&times[..4], &with_nan, &cfg), Ok(Some(times[3])));
    assert!(matches!(tactile_release(&times, &loads[..3], &cfg), Err(GraspError::LengthMismatch { .. })));
}

/// Catches a drop rule that ignores the hand's command: a loss of load
/// while the hand is told to let go (the protocol's release) is a release,
/// without any opening reported; the same loss without it is a drop.
#[test]
fn a_loss_of_load_while_releasing_is_a_release() {
    for (releasing, expected) in [(true, GraspState::Released), (false, GraspState::Dropped)] {
        let mut d = GraspDetector::new(GraspDetectorConfig::default()).expect("valid");
        d.update(GraspScan::load(0.0, 20_000.0));
        d.update(GraspScan::load(0.1, 21_000.0));
        let mut scan = GraspScan::load(0.2, 100.0);
        if releasing {
            scan = scan.releasing();
        }
        assert_eq!(d.update(scan).state, expected);
    }
}

/// Catches a reference against the running peak: a grasp that relaxes to
/// a third of its peak over seconds, then collapses, is released at the
/// collapse.
#[test]
fn tactile_release_is_the_collapse_not_a_slow_relaxation() {
    let cfg = GraspDetectorConfig::default();
    let dt = 0.1;
    let mut loads: Vec<f64> = (0..100).map(|k| 100_000.0 - 700.0 * k as f64).collect();
    loads.extend([20_000.0, 800.0, 500.0, 400.0]);
    let times: Vec<f64> = (0..loads.len()).map(|k| k as f64 * dt).collect();
    let release = tactile_release(&times, &loads, &cfg).expect("same lengths").expect("released");
    assert!((release - times[101]).abs() < 1e-12, "release at {release} s");
}

/// Catches a delay with the wrong sign, and entries counted per scan rather
/// than per episode; held time counts Holding and Slipping only.
#[test]
fn drop_delay_and_hold_summary() {
    use GraspState::{Dropped, Holding, Idle, Released, Slipping};
    let times = [0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7];
    let states = [Idle, Holding, Slipping, Holding, Dropped, Dropped, Idle, Holding];
    let delay = drop_detection_delay_s(&times, &states, 0.45).expect("same lengths").expect("dropped");
    assert!((delay + 0.05).abs() < 1e-12, "{delay}");
    assert_eq!(drop_detection_delay_s(&times[..4], &states[..4], 0.3), Ok(None));
    let mut summary = hold_summary(&times, &states).expect("same lengths");
    assert_eq!((summary.dropped_entries, summary.released_entries), (1, 0));
    assert!((summary.held_s - 0.3).abs() < 1e-12, "{}", summary.held_s);
    summary += hold_summary(&[0.0, 30.0, 60.0], &[Holding, Released, Idle]).expect("same lengths");
    assert_eq!(summary.released_entries, 1);
    let per_minute = summary.dropped_per_held_minute().expect("held");
    assert!((per_minute - 1.0 / (30.3 / 60.0)).abs() < 1e-12);
    assert_eq!(HoldSummary::default().dropped_per_held_minute(), None);
}

/// Catches AUC orientation, ties not counted half (`-0 == 0` included), and
/// the one-class case.
#[test]
fn roc_auc_on_hand_computed_cases() {
    let labels = [true, true, false, false];
    assert_eq!(roc_auc(&[0.9, 0.8, 0.2, 0.1], &labels), Ok(Some(1.0)));
    assert_eq!(roc_auc(&[0.1, 0.2, 0.8, 0.9], &labels), Ok(Some(0.0)));
    assert_eq!(roc_auc(&[0.5; 4], &labels), Ok(Some(0.5)));
    assert_eq!(roc_auc(&[-0.0, 0.0], &[true, false]), Ok(Some(0.5)));
    // Positives 0.9, 0.5, 0.5 against negatives 0.5, 0.1: of the 6 pairs,
    // 4 won and 2 tied: (4 + 2/2) / 6.
    let scores = [0.9, 0.5, 0.5, 0.5, 0.1];
    let labels = [true, true, true, false, false];
    let auc = roc_auc(&scores, &labels).expect("valid").expect("two classes");
    assert!((auc - 5.0 / 6.0).abs() < 1e-12, "{auc}");
    assert_eq!(roc_auc(&[0.1, 0.2], &[true, true]), Ok(None));
    assert_eq!(roc_auc(&[], &[]), Ok(None));
    assert_eq!(roc_auc(&[0.1, f64::NAN], &[true, false]), Err(GraspError::NanScore { index: 1 }));
    assert!(matches!(roc_auc(&[0.1], &[true, false]), Err(GraspError::LengthMismatch { .. })));
}

/// Catches a curve that splits tied scores into separate points (its area
/// would then depend on the input order) or misses an end point.
#[test]
fn roc_curve_has_one_point_per_distinct_score_and_the_area_of_roc_auc() {
    let scores = [0.9, 0.5, 0.5, 0.5, 0.1];
    let labels = [true, true, true, false, false];
    let curve = roc_curve(&scores, &labels).expect("valid").expect("two classes");
    assert_eq!(curve.thresholds, vec![f64::INFINITY, 0.9, 0.5, 0.1]);
    assert_eq!(curve.tpr, vec![0.0, 1.0 / 3.0, 1.0, 1.0]);
    assert_eq!(curve.fpr, vec![0.0, 0.0, 0.5, 1.0]);
    assert!((curve.area() - 5.0 / 6.0).abs() < 1e-12);
    assert_eq!(roc_curve(&[0.3], &[false]), Ok(None));
}
