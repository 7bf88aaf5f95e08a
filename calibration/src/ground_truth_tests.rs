//! The ground truth on synthetic marker tracks.

use nalgebra::{Isometry3, Point3, Vector3};
use slidetrack_core::PerFinger;
use slidetrack_session::{ArucoDetection, SimTruth};

use super::*;

fn ms(t: u64) -> TimeNs {
    TimeNs(t * 1_000_000)
}

fn seen(p_in_camera: [f64; 3], on_axis: f64) -> ArucoDetection {
    ArucoDetection {
        detected: true,
        marker_id: Some(7),
        position_in_camera_m: Some(p_in_camera),
        position_on_axis_m: Some(on_axis),
        ..ArucoDetection::missed()
    }
}

#[test]
fn scan_and_camera_times_merge_into_one_increasing_grid() {
    let scans = [ms(0), ms(10), ms(20), ms(30), ms(40)];
    let positions = [(ms(0), 0.0), (ms(33), 1.0), (ms(40), 2.0), (ms(66), 3.0)];
    let grid = merge_times(&scans, &positions);
    let summary: Vec<(u64, bool, Option<usize>)> =
        grid.iter().map(|g| (g.t.0 / 1_000_000, g.scan, g.measurement)).collect();
    assert_eq!(
        summary,
        [
            (0, true, Some(0)),
            (10, true, None),
            (20, true, None),
            (30, true, None),
            (33, false, Some(1)),
            (40, true, Some(2)),
            (66, false, Some(3))
        ]
    );
}

#[test]
fn recorded_positions_start_at_zero_and_misses_are_counted() {
    let detections = vec![
        (ms(0), ArucoDetection::missed()),
        (ms(33), seen([0.0, 0.0, 0.3], 0.004)),
        (ms(66), ArucoDetection::missed()),
        (ms(100), seen([0.0, 0.01, 0.3], 0.014)),
    ];
    let m = marker_positions(&detections, AxisSource::Recorded, None).unwrap();
    assert_eq!(m.positions, vec![(ms(33), 0.0), (ms(100), 0.014 - 0.004)]);
    assert_eq!((m.missing, m.frames), (2, 4));
    let none = vec![(ms(0), ArucoDetection::missed())];
    assert!(matches!(
        marker_positions(&none, AxisSource::Recorded, None),
        Err(GroundTruthError::NoDetections { frames: 1 })
    ));
    assert!(matches!(
        marker_positions(&detections, AxisSource::Config, None),
        Err(GroundTruthError::RigConfig { .. })
    ));
}

/// Marker positions in the camera frame for travels `p` along the default rig's axis.
fn track_in_camera(travels: &[f64]) -> (Vec<(TimeNs, ArucoDetection)>, SlidingAxis) {
    let axis = axis_from_rig_config("").unwrap();
    let camera_from_hand: Isometry3<f64> = axis.hand_from_camera.inverse();
    let detections = travels
        .iter()
        .enumerate()
        .map(|(k, &p)| {
            let in_hand = Point3::new(0.12, 0.003, 0.03) + axis.axis_in_hand.into_inner() * p;
            let in_camera = camera_from_hand * in_hand;
            (ms(33 * k as u64), seen(in_camera.coords.into(), p))
        })
        .collect();
    (detections, axis)
}

#[test]
fn the_config_axis_and_the_estimated_axis_give_the_recorded_positions() {
    let travels: Vec<f64> = (0..60).map(|k| 0.001 * k as f64 + if k % 2 == 0 { 0.0 } else { 2e-5 }).collect();
    let (detections, axis) = track_in_camera(&travels);
    let recorded = marker_positions(&detections, AxisSource::Recorded, None).unwrap();
    let rig = "[geometry]\nsliding_axis_in_hand = [0.0, 0.0, -1.0]\n";
    let config = marker_positions(&detections, AxisSource::Config, Some(rig)).unwrap();
    let estimated = marker_positions(&detections, AxisSource::Estimate, None).unwrap();
    for ((a, b), c) in recorded.positions.iter().zip(&config.positions).zip(&estimated.positions) {
        assert!((a.1 - b.1).abs() < 1e-12, "{a:?} {b:?}");
        assert!((a.1 - c.1).abs() < 1e-9, "{a:?} {c:?}");
    }
    let expected = axis.hand_from_camera.rotation.inverse() * axis.axis_in_hand.into_inner();
    assert!((estimated.axis_in_camera.unwrap() - expected).norm() < 1e-6);
    assert!((config.axis_in_camera.unwrap() - expected).norm() < 1e-12);
}

#[test]
fn the_estimated_axis_follows_the_hint_and_needs_motion() {
    let points: Vec<Point3<f64>> =
        (0..20).map(|k| Point3::new(0.0, 0.0, 0.3) + Vector3::y() * (0.002 * k as f64)).collect();
    let up = estimate_axis(&points, Some(-Vector3::y())).unwrap();
    assert!((up.into_inner() + Vector3::y()).norm() < 1e-9);
    let forward = estimate_axis(&points, None).unwrap();
    assert!((forward.into_inner() - Vector3::y()).norm() < 1e-9);
    let still = vec![Point3::new(0.0, 0.0, 0.3); 10];
    assert!(matches!(estimate_axis(&still, None), Err(GroundTruthError::AxisEstimate { .. })));
    assert!(matches!(estimate_axis(&points[..2], None), Err(GroundTruthError::AxisEstimate { .. })));
}

/// A stick-slip trajectory: rest, then slides of 1-2 cm at up to 4 cm/s.
fn stick_slip(t_s: f64) -> (f64, f64) {
    let period = 2.5;
    let cycle = (t_s / period).floor();
    let phase = t_s - cycle * period;
    let (slide_s, travel_m) = (0.8, 0.012);
    let before = cycle * travel_m;
    if phase < period - slide_s {
        return (before, 0.0);
    }
    // Raised-cosine velocity over the slide.
    let x = (phase - (period - slide_s)) / slide_s;
    let v = travel_m / slide_s * (1.0 - (std::f64::consts::TAU * x).cos());
    let p = travel_m * (x - (std::f64::consts::TAU * x).sin() / std::f64::consts::TAU);
    (before + p, v)
}

/// A deterministic, roughly Gaussian noise (sum of 4 uniforms) of standard deviation `std`.
fn noise(k: u64, std: f64) -> f64 {
    let u = |i: u64| {
        let z = (k.wrapping_mul(4) + i).wrapping_mul(0x9E37_79B9_7F4A_7C15);
        let z = (z ^ (z >> 29)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        ((z ^ (z >> 32)) >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    };
    (u(0) + u(1) + u(2) + u(3)) * std * 3f64.sqrt()
}

#[test]
fn a_noisy_stick_slip_track_is_smoothed_within_a_millimetre_and_5_mm_per_s() {
    // 20 s of scans at 100 Hz, marker at 30 Hz with 0.3 mm noise, 5 % of frames missed.
    let scans: Vec<TimeNs> = (0..2000).map(|k| TimeNs(k * 10_000_000)).collect();
    let positions: Vec<(TimeNs, f64)> = (0..600u64)
        .filter(|k| k % 20 != 7)
        .map(|k| {
            let t = TimeNs(k * 33_333_333);
            (t, stick_slip(t.as_secs_f64()).0 + noise(k, 3e-4))
        })
        .collect();
    let truth: Vec<(TimeNs, SimTruth)> = scans
        .iter()
        .map(|t| {
            let (position, velocity) = stick_slip(t.as_secs_f64());
            let forces = PerFinger::default();
            (
                *t,
                SimTruth {
                    position,
                    velocity,
                    sliding: velocity > 0.0,
                    supported: false,
                    normal_force: forces,
                    friction_force: forces,
                },
            )
        })
        .collect();
    let gt = smooth_ground_truth(&scans, &positions, &default_params()).unwrap();
    let sliding = gt.sliding();
    assert_eq!(sliding.len(), scans.len());
    let rmse =
        rmse_against_truth(&sliding, &truth, positions[0].0, positions[positions.len() - 1].0).unwrap();
    assert!(rmse.position_m < 1e-3 && rmse.velocity_mps < 5e-3, "{rmse:?}");
    // The filter alone lags: the smoother is better.
    let filtered =
        rmse_against_truth(&gt.filtered(), &truth, positions[0].0, positions[positions.len() - 1].0).unwrap();
    assert!(filtered.velocity_mps > rmse.velocity_mps, "{filtered:?} vs {rmse:?}");
    assert_eq!(gt.measurements().len(), positions.len());
    assert_eq!(gt.rejected(), 0);
}

#[test]
fn an_outlier_is_rejected_and_does_not_move_the_ground_truth() {
    let scans: Vec<TimeNs> = (0..600).map(|k| TimeNs(k * 10_000_000)).collect();
    let mut positions: Vec<(TimeNs, f64)> =
        (0..180u64).map(|k| (TimeNs(k * 33_333_333), 0.001 * (k as f64 / 30.0) + noise(k, 2e-4))).collect();
    let clean = smooth_ground_truth(&scans, &positions, &default_params()).unwrap().sliding();
    positions[90].1 += 0.02;
    let gt = smooth_ground_truth(&scans, &positions, &default_params()).unwrap();
    assert_eq!(gt.rejected(), 1);
    assert!(gt.measurements()[90].1.rejected);
    let worst =
        gt.sliding().iter().zip(&clean).map(|(a, b)| (a.1.position - b.1.position).abs()).fold(0.0, f64::max);
    // The rejected sample only widens the gap between its neighbours.
    assert!(worst < 2e-4, "{worst}");
}

#[test]
fn the_rmse_of_the_truth_against_itself_is_zero_after_rezeroing() {
    let truth: Vec<(TimeNs, SimTruth)> = (0..100)
        .map(|k| {
            (ms(10 * k), SimTruth { position: 0.5 + 0.001 * k as f64, velocity: 0.1, ..SimTruth::default() })
        })
        .collect();
    let estimate: Vec<(TimeNs, GroundTruthSliding)> = truth
        .iter()
        .map(|(t, s)| {
            (
                *t,
                GroundTruthSliding {
                    position: s.position - 0.5 - 0.002,
                    velocity: 0.1,
                    covariance: [[0.0; 2]; 2],
                },
            )
        })
        .collect();
    // Zero at 20 ms (truth 0.502): estimate - (truth - 0.502) = 0.
    let r = rmse_against_truth(&estimate, &truth, ms(20), ms(500)).unwrap();
    assert!(r.position_m < 1e-12 && r.velocity_mps < 1e-12, "{r:?}");
    assert_eq!(r.samples, 49);
    // Between samples the truth is interpolated.
    let between =
        [(ms(25), GroundTruthSliding { position: 0.0005, velocity: 0.1, covariance: [[0.0; 2]; 2] })];
    assert!(rmse_against_truth(&between, &truth, ms(20), ms(500)).unwrap().position_m < 1e-12);
}
