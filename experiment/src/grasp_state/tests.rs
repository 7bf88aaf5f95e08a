use slidetrack_core::{FingerReading, PerFinger, SensorLayout, TactileLayout};

use super::*;

/// Two 2x2 patches: 8 taxels.
fn info() -> TactileInfo {
    TactileInfo {
        device: "test".into(),
        rate_hz: 100.0,
        layout: TactileLayout {
            sensors: vec![
                SensorLayout::grid("left", "p", "thumb", 2, 2),
                SensorLayout::grid("right", "p", "index", 2, 2),
            ],
        },
        fingers: PerFinger {
            thumb: FingerReading::mean("left"),
            index: FingerReading::mean("right"),
            middle: FingerReading::mean("right"),
        },
    }
}

fn stage() -> SlipStage {
    SlipStage::new(GraspDetectorConfig::default(), &info()).unwrap()
}

/// A scan at `t_s` (s): taxel `k` has x = `vx[k] t`, y = `vy[k] t` and z = `z[k]`.
fn scan(t_s: f64, v: &[(f64, f64)], z: &[f64]) -> Vec<[f64; 3]> {
    v.iter().zip(z).map(|((vx, vy), z)| [vx * t_s, vy * t_s, *z]).collect()
}

// Catches: a load that is not the plain sum of z over both sensors (a mean,
// one sensor only, |z|), and a score that is not the RMS over taxels of the
// shear-rate magnitude (the mean of magnitudes, a sum over taxels, x or y
// alone, or a rate per scan instead of per second).
#[test]
fn load_is_the_sum_of_z_and_the_score_the_rms_shear_rate() {
    let z = [1000.0, 2000.0, 3000.0, 4000.0, 500.0, 600.0, -700.0, 800.0];
    // Every taxel at (300, 400) counts/s: |rate| 500 on each, RMS 500.
    let mut s = stage();
    let mut last = SlipEstimate::default();
    for k in 0..300 {
        let t = k as f64 * 0.01;
        last = s.on_scan(TimeNs::from_secs_f64(t), &scan(t, &[(300.0, 400.0); 8], &z));
    }
    assert_eq!(last.load, 11_200.0);
    assert!((last.slip_score - 500.0).abs() < 1.0, "{}", last.slip_score);
    // Half of the taxels still: RMS sqrt(4 * 500^2 / 8) = 353.6 (a mean of
    // magnitudes would give 250).
    let mut s = stage();
    let v: Vec<(f64, f64)> = (0..8).map(|k| if k % 2 == 0 { (0.0, 500.0) } else { (0.0, 0.0) }).collect();
    for k in 0..300 {
        let t = k as f64 * 0.01;
        last = s.on_scan(TimeNs::from_secs_f64(t), &scan(t, &v, &z));
    }
    let expected = (4.0 * 500.0f64.powi(2) / 8.0).sqrt();
    assert!((last.slip_score - expected).abs() < 1.0, "{} vs {expected}", last.slip_score);
    assert_eq!(shear_rate_rms(&[]), 0.0);
}

/// A held load of 20,000 counts that falls to 100 at 2 s, shear moving at
/// 1000 counts/s, values refreshed every 0.1 s and recorded every 0.025 s
/// (`repeat` 4) or once per refresh (`repeat` 1). Returns the estimates at
/// the refresh times.
fn refreshed(repeat: usize) -> Vec<(f64, SlipEstimate)> {
    let mut s = stage();
    let mut out = Vec::new();
    for refresh in 0..40 {
        let t0 = refresh as f64 * 0.1;
        let load = if refresh < 2 {
            0.0
        } else if t0 < 2.0 {
            20_000.0 + 50.0 * t0
        } else {
            100.0
        };
        let values = scan(t0, &[(1000.0, 0.0); 8], &[load / 8.0; 8]);
        for k in 0..repeat {
            let t = t0 + k as f64 * 0.1 / repeat as f64;
            let e = s.on_scan(TimeNs::from_secs_f64(t), &values);
            if k == 0 {
                out.push((t, e));
            }
        }
    }
    out
}

// Catches: a stage that steps the derivative filter on repeated rows (its
// rate would sink between refreshes and jump at them, so the score at the
// refresh times would differ from the deduplicated stream's), and states
// decided on repeats.
#[test]
fn repeated_rows_give_the_estimates_of_the_deduplicated_stream() {
    let (repeated, once) = (refreshed(4), refreshed(1));
    assert_eq!(repeated, once);
    let states: Vec<GraspStateName> = once.iter().map(|(_, e)| e.state).collect();
    assert_eq!(states[0], GraspStateName::Idle);
    assert_eq!(states[2], GraspStateName::Holding);
    assert_eq!(states[20], GraspStateName::Dropped, "the load fell at 2 s: {states:?}");
    assert_eq!(states[21], GraspStateName::Idle);
    assert!(once[10].1.slip_score > 900.0, "{:?}", once[10]);
}

// Catches: the opening not reaching the detector (a release would read as a
// drop), and a missing opening (`None`) clearing the latest one.
#[test]
fn an_opened_gripper_makes_the_fall_a_release() {
    let run = |opening_at_fall: Option<f64>| {
        let mut s = stage();
        s.set_opening(Some(0.030));
        let z = |load: f64| vec![[0.0, 0.0, load / 8.0]; 8];
        s.on_scan(TimeNs::from_secs_f64(0.0), &z(20_000.0));
        s.set_opening(None);
        s.on_scan(TimeNs::from_secs_f64(0.1), &z(21_000.0));
        s.set_opening(opening_at_fall);
        s.on_scan(TimeNs::from_secs_f64(0.2), &z(50.0)).state
    };
    assert_eq!(run(None), GraspStateName::Dropped);
    assert_eq!(run(Some(0.032)), GraspStateName::Dropped, "2 mm is under the 5 mm release opening");
    assert_eq!(run(Some(0.040)), GraspStateName::Released);
}

// Catches: metadata that does not hold the settings the stage ran with, or
// not the score's unit; a short or non-finite scan that panics or writes a
// number JSON cannot hold.
#[test]
fn metadata_holds_the_settings_and_bad_scans_give_finite_numbers() {
    let s = stage();
    let meta = s.metadata().unwrap();
    let cfg: GraspDetectorConfig = serde_json::from_str(&meta["detector"]).unwrap();
    assert_eq!(cfg, GraspDetectorConfig::default());
    assert_eq!(meta["slip_score_unit"], "counts/s");
    let filter: DerivativeFilterConfig = serde_json::from_str(&meta["derivative_filter"]).unwrap();
    assert_eq!(filter.outlier_gate_sigma, 0.0);
    let mut s = stage();
    let e = s.on_scan(TimeNs::from_secs_f64(0.0), &[[1.0, 2.0, f64::NAN]]);
    let e2 = s.on_scan(TimeNs::from_secs_f64(0.01), &[[3.0, 4.0, 5.0]; 3]);
    for x in [e.load, e.load_ratio, e.slip_score, e2.load, e2.slip_score] {
        assert!(x.is_finite(), "{e:?} {e2:?}");
    }
    assert!(serde_json::to_string(&e).is_ok());
}
