//! The fit against closed-form maps, its guards, and the file.

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use slidetrack_core::{SensorLayout, TactileLayout};

use super::error::TactileForceError;
use super::eval::{axis_errors, fit_axis_slopes, fit_global_scale};
use super::features::{ForceModelKind, TaxelForceMap};
use super::file::{FORMAT, SensorForceMap, TactileForceCalibration, VERSION};
use super::fit::fit_taxel;

/// A map with cross-talk everywhere and, when `quadratic`, second-order terms.
fn known_map(quadratic: bool) -> TaxelForceMap {
    TaxelForceMap {
        offset_n: [0.01, -0.02, 0.03],
        linear_n_per_count: [
            [1.2e-3, 0.1e-3, -0.05e-3],
            [-0.08e-3, 0.9e-3, 0.07e-3],
            [0.04e-3, -0.06e-3, 0.7e-3],
        ],
        quadratic_n_per_count2: quadratic.then_some([
            [1e-8, 0.0, 2e-8, 0.0, -1e-8, 0.0],
            [0.0, -1e-8, 0.0, 3e-8, 0.0, 0.0],
            [0.0, 0.0, -1.5e-7, 0.0, 1e-8, 2e-8],
        ]),
    }
}

fn counts(n: usize, seed: u64) -> Vec<[f64; 3]> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..n)
        .map(|_| {
            [rng.random_range(-800.0..800.0), rng.random_range(-800.0..800.0), rng.random_range(0.0..2000.0)]
        })
        .collect()
}

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol
}

#[test]
fn a_linear_map_with_cross_talk_is_recovered_exactly() {
    let truth = known_map(false);
    let c = counts(200, 1);
    let f: Vec<[f64; 3]> = c.iter().map(|c| truth.force_n(*c)).collect();
    let fit = fit_taxel(ForceModelKind::Linear, 0, &c, &f).unwrap();
    for (got, want) in fit.map.offset_n.iter().zip(truth.offset_n) {
        assert!(close(*got, want, 1e-9), "{:?}", fit.map);
    }
    for (got, want) in
        fit.map.linear_n_per_count.iter().flatten().zip(truth.linear_n_per_count.iter().flatten())
    {
        assert!(close(*got, *want, 1e-12), "{:?}", fit.map);
    }
    assert_eq!(fit.outliers, 0);
    assert!(fit.rms_n.iter().all(|e| *e < 1e-9), "{:?}", fit.rms_n);
}

#[test]
fn the_quadratic_model_recovers_a_quadratic_map_that_the_linear_one_cannot() {
    let truth = known_map(true);
    let c = counts(400, 2);
    let f: Vec<[f64; 3]> = c.iter().map(|c| truth.force_n(*c)).collect();
    let quadratic = fit_taxel(ForceModelKind::Quadratic, 0, &c, &f).unwrap();
    assert!(quadratic.rms_n.iter().all(|e| *e < 1e-9), "{:?}", quadratic.rms_n);
    let q = quadratic.map.quadratic_n_per_count2.unwrap();
    assert!(close(q[2][2], -1.5e-7, 1e-15), "{q:?}");
    let linear = fit_taxel(ForceModelKind::Linear, 0, &c, &f).unwrap();
    assert!(linear.rms_n[2] > 1e-2, "the z curvature is missed: {:?}", linear.rms_n);
}

#[test]
fn spikes_are_left_out_of_the_fit() {
    let truth = known_map(false);
    let c = counts(500, 3);
    let f: Vec<[f64; 3]> = c.iter().map(|c| truth.force_n(*c)).collect();
    let mut spiked = c.clone();
    spiked[10][2] += 2500.0;
    spiked[300][0] -= 1800.0;
    let fit = fit_taxel(ForceModelKind::Linear, 0, &spiked, &f).unwrap();
    assert_eq!(fit.outliers, 2);
    assert!(close(fit.map.linear_n_per_count[2][2], 0.7e-3, 1e-12), "{:?}", fit.map);
}

#[test]
fn bad_data_is_refused_with_the_taxel_named() {
    let c = counts(100, 4);
    let f: Vec<[f64; 3]> = c.iter().map(|c| known_map(false).force_n(*c)).collect();
    let e = fit_taxel(ForceModelKind::Linear, 5, &c[..50], &f).unwrap_err();
    assert!(matches!(e, TactileForceError::LengthMismatch { taxel: 5, counts: 50, forces: 100 }), "{e}");
    let e = fit_taxel(ForceModelKind::Quadratic, 1, &c[..20], &f[..20]).unwrap_err();
    assert!(e.to_string().contains("taxel 1: 20 scans are too few"), "{e}");
    // Pressed along z only: x and y never move, their terms are not determined.
    let z_only: Vec<[f64; 3]> = c.iter().map(|c| [0.0, 0.0, c[2]]).collect();
    let e = fit_taxel(ForceModelKind::Linear, 2, &z_only, &f).unwrap_err();
    assert!(matches!(e, TactileForceError::Degenerate { taxel: 2, rank: 2, terms: 4 }), "{e}");
    let e = fit_taxel(ForceModelKind::Linear, 3, &c, &vec![[0.0; 3]; c.len()]).unwrap_err();
    assert!(matches!(e, TactileForceError::NoForce { taxel: 3 }), "{e}");
    let mut nan = c.clone();
    nan[7][1] = f64::NAN;
    assert!(matches!(
        fit_taxel(ForceModelKind::Linear, 0, &nan, &f),
        Err(TactileForceError::NotFinite { .. })
    ));
}

#[test]
fn errors_are_per_axis_and_relative_to_the_reference_range() {
    let e = axis_errors([([1.0, 0.0, 2.0], [0.0, 0.0, 2.0]), ([0.0, 1.0, 4.0], [2.0, 0.0, 6.0])]);
    assert_eq!(e.samples, 2);
    assert!(close(e.rms_n[0], (2.5f64).sqrt(), 1e-12) && close(e.rms_n[2], 2f64.sqrt(), 1e-12));
    assert_eq!(e.max_abs_n, [2.0, 1.0, 2.0]);
    assert_eq!(e.range_n, [2.0, 0.0, 4.0]);
    let r = e.rms_of_range();
    assert!(close(r[2], 2f64.sqrt() / 4.0, 1e-12) && r[1].is_infinite());
}

#[test]
fn the_trivial_baselines_fit_their_closed_forms() {
    let c = [[1.0, 2.0, 3.0], [2.0, 4.0, 6.0]];
    let f = c.map(|c| c.map(|v| 0.5 * v));
    assert!(close(fit_global_scale(&c, &f), 0.5, 1e-12));
    let f2 = c.map(|c| [2.0 * c[0] + 1.0, -c[1], 0.25 * c[2] - 3.0]);
    let s = fit_axis_slopes(&c, &f2);
    assert!(close(s.slope_n_per_count[0], 2.0, 1e-12) && close(s.intercept_n[0], 1.0, 1e-12));
    assert!(close(s.slope_n_per_count[2], 0.25, 1e-12) && close(s.intercept_n[2], -3.0, 1e-12));
    assert_eq!(s.force_n([1.0, 2.0, 3.0]), f2[0]);
}

fn calibration() -> TactileForceCalibration {
    TactileForceCalibration {
        format: FORMAT.into(),
        version: VERSION,
        model: ForceModelKind::Quadratic,
        baseline: "tare".into(),
        reference: "/tactile/reference".into(),
        fitted_on: vec!["a.mcap".into()],
        fit_rms_n: [0.01, 0.02, 0.03],
        fit_range_n: [1.0, 1.0, 2.0],
        sensors: vec![
            SensorForceMap { name: "left".into(), taxels: vec![known_map(true); 2] },
            SensorForceMap { name: "right".into(), taxels: vec![known_map(true)] },
        ],
    }
}

fn layout(sensors: &[(&str, u32)]) -> TactileLayout {
    TactileLayout {
        sensors: sensors.iter().map(|(n, cols)| SensorLayout::grid(n, "sim", "thumb", 1, *cols)).collect(),
    }
}

#[test]
fn the_file_round_trips_and_applies_per_taxel() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("cal.toml");
    let cal = calibration();
    cal.save(&path).unwrap();
    let back = TactileForceCalibration::load(&path).unwrap();
    assert_eq!(back, cal);
    back.check_layout(&layout(&[("left", 2), ("right", 1)])).unwrap();
    let scan = [[100.0, -50.0, 900.0], [0.0; 3], [10.0, 20.0, 30.0]];
    let forces = back.forces_n(&scan);
    assert_eq!(forces, scan.map(|c| known_map(true).force_n(c)).to_vec());
}

#[test]
fn a_wrong_file_or_layout_is_refused_with_a_reason() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("cal.toml");
    let cal = calibration();
    let e = cal.check_layout(&layout(&[("left", 2), ("right", 2)])).unwrap_err();
    assert!(e.to_string().contains("\"right\" with 1 taxels where the rig has \"right\" with 2"), "{e}");
    let e = cal.check_layout(&layout(&[("left", 2)])).unwrap_err();
    assert!(e.to_string().contains("[left, right], the rig [left]"), "{e}");
    let mut v2 = cal.clone();
    v2.version = 2;
    v2.save(&path).unwrap();
    let e = TactileForceCalibration::load(&path).unwrap_err().to_string();
    assert!(e.contains("cal.toml") && e.contains("version 2"), "{e}");
    let mut mixed = cal.clone();
    mixed.sensors[1].taxels[0].quadratic_n_per_count2 = None;
    mixed.save(&path).unwrap();
    let e = TactileForceCalibration::load(&path).unwrap_err().to_string();
    assert!(e.contains("sensor \"right\" taxel 0: a linear map in a quadratic calibration"), "{e}");
    std::fs::write(&path, "format = 3\n").unwrap();
    let e = TactileForceCalibration::load(&path).unwrap_err().to_string();
    assert!(e.contains("cal.toml: line 1: ") && e.contains("string") && !e.contains('\n'), "{e}");
}
