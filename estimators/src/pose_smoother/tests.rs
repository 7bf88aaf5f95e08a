//! The pose smoother against closed forms (noise-free constant motion, the
//! 1-D smoother per axis), on noisy data of a known trajectory, and on the
//! traps of orientation: the double cover, rotations through 180 degrees,
//! marker flips.

use std::f64::consts::PI;

use approx::assert_relative_eq;
use nalgebra::{Quaternion, UnitQuaternion, Vector3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

use super::*;
use crate::constant_velocity::{CvParams, CvSample};
use crate::orientation::quaternion::exp;
use crate::rts::Gate;

/// A true pose: position (m) and `frame_from_object`.
type Truth = (Vector3<f64>, UnitQuaternion<f64>);

/// Marker poses of `truth` at `times`, with noise of standard deviation
/// `sigma_m` per position axis and `sigma_rad` per rotation axis (the
/// rotation noise on the left, in the measurement frame).
fn measured(
    times: &[f64],
    truth: impl Fn(f64) -> Truth,
    sigma_m: f64,
    sigma_rad: f64,
    seed: u64,
) -> Vec<PoseSample> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let unit = Normal::new(0.0, 1.0).unwrap();
    let mut noise = |sigma: f64| Vector3::from_fn(|_, _| sigma * unit.sample(&mut rng));
    times
        .iter()
        .map(|&t_s| {
            let (p, q) = truth(t_s);
            let position_m = p + noise(sigma_m);
            let orientation = exp(&noise(sigma_rad)) * q;
            PoseSample { t_s, measurement: Some(PoseMeasurement { position_m, orientation }) }
        })
        .collect()
}

fn times_30_hz(n: usize) -> Vec<f64> {
    (0..n).map(|k| k as f64 / 30.0).collect()
}

fn tilted(deg_per_s: f64) -> Vector3<f64> {
    Vector3::new(0.3, -0.5, 0.8).normalize() * deg_per_s.to_radians()
}

/// Root mean square of the position error (3-D, m) and of the rotation
/// angle (rad) of `track` (or of the measurements) against `truth`.
fn rmse(
    poses: impl Iterator<Item = (f64, Vector3<f64>, UnitQuaternion<f64>)>,
    truth: impl Fn(f64) -> Truth,
) -> (f64, f64) {
    let (mut sp, mut sq, mut n) = (0.0, 0.0, 0.0);
    for (t, p, q) in poses {
        let (tp, tq) = truth(t);
        sp += (p - tp).norm_squared();
        sq += q.angle_to(&tq).powi(2);
        n += 1.0;
    }
    ((sp / n).sqrt(), (sq / n).sqrt())
}

fn of_track(track: &[SmoothedPose]) -> impl Iterator<Item = (f64, Vector3<f64>, UnitQuaternion<f64>)> + '_ {
    track.iter().map(|s| (s.t_s, s.position_m, s.orientation))
}

fn of_measurements(
    samples: &[PoseSample],
) -> impl Iterator<Item = (f64, Vector3<f64>, UnitQuaternion<f64>)> + '_ {
    samples.iter().filter_map(|s| s.measurement.map(|m| (s.t_s, m.position_m, m.orientation)))
}

/// Parameters for noise-free data: tiny `R`, diffuse velocities.
fn exact_params() -> PoseSmootherParams {
    PoseSmootherParams {
        q_position_m2_per_s: 1e-10,
        q_velocity_m2_per_s3: 1e-3,
        r_position_m2: 1e-16,
        q_orientation_rad2_per_s: 1e-10,
        q_angular_velocity_rad2_per_s3: 1e-2,
        r_orientation_rad2: 1e-16,
        p0_position_m2: 1e-4,
        p0_velocity_m2_per_s2: 1.0,
        p0_orientation_rad2: 1e-2,
        p0_angular_velocity_rad2_per_s2: 10.0,
        gate: None,
    }
}

/// Checks every pose of `track` against `truth` and the velocities against
/// `v`, `omega` from sample `from_velocity` on.
fn assert_exact(
    track: &[SmoothedPose],
    truth: impl Fn(f64) -> Truth,
    v: Vector3<f64>,
    omega: Vector3<f64>,
    from_velocity: usize,
) {
    for (k, s) in track.iter().enumerate() {
        let (p, q) = truth(s.t_s);
        assert!((s.position_m - p).norm() < 1e-6, "position at {k}: {} vs {p}", s.position_m);
        assert!(
            s.orientation.angle_to(&q) < 1e-6,
            "orientation at {k}: {} rad off",
            s.orientation.angle_to(&q)
        );
        if k >= from_velocity {
            assert!((s.velocity_m_per_s - v).norm() < 1e-6, "velocity at {k}: {}", s.velocity_m_per_s);
            assert!(
                (s.angular_velocity_rad_per_s - omega).norm() < 1e-6,
                "omega at {k}: {}",
                s.angular_velocity_rad_per_s
            );
        }
    }
}

/// Constant linear velocity and 40 deg/s about a tilted axis, measured
/// without noise, some samples missing: the filter and the smoother give
/// the truth back; the smoother also the velocities from the first sample.
/// Catches a wrong sign or frame of `omega` (right- instead of
/// left-multiplied), a wrong `F`, or a smoother correction in the wrong
/// tangent space.
#[test]
fn constant_motion_without_noise_is_recovered_exactly() {
    let (v, omega) = (Vector3::new(0.03, -0.02, 0.01), tilted(40.0));
    let q0 = UnitQuaternion::from_euler_angles(0.4, -0.2, 1.0);
    let truth = |t: f64| (Vector3::new(0.1, 0.2, 0.5) + v * t, exp(&(omega * t)) * q0);
    let mut samples = measured(&times_30_hz(120), truth, 0.0, 0.0, 1);
    for k in [5, 6, 40, 77, 119] {
        samples[k].measurement = None;
    }
    let out = smooth_poses(&exact_params(), &samples).unwrap();
    assert_exact(&out.smoothed, truth, v, omega, 0);
    assert_exact(&out.filtered, truth, v, omega, 10);
    assert!(out.measurements.iter().filter(|m| **m == MeasurementUse::Missing).count() == 5);
}

/// The same with 120 deg/s from 150 degrees, through 180 and 360 degrees,
/// and from exactly 180 degrees (scalar part 0): the shortest-path
/// logarithm keeps the innovations small.
#[test]
fn rotations_through_180_degrees_are_tracked() {
    let omega = tilted(120.0);
    let axis = omega.normalize();
    for start_deg in [150.0, 180.0] {
        let q0 = UnitQuaternion::from_scaled_axis(axis * f64::to_radians(start_deg));
        let truth = |t: f64| (Vector3::zeros(), exp(&(omega * t)) * q0);
        let samples = measured(&times_30_hz(100), truth, 0.0, 0.0, 2);
        let out = smooth_poses(&exact_params(), &samples).unwrap();
        assert_exact(&out.smoothed, truth, Vector3::zeros(), omega, 0);
        assert_exact(&out.filtered, truth, Vector3::zeros(), omega, 10);
    }
}

/// An object at rest at exactly 180 degrees measured with 1 degree of
/// noise: the measured quaternions' scalar parts scatter around 0 with both
/// signs. The filter is right-invariant (`Log(q_m C (q C)^-1) = Log(q_m
/// q^-1)`), so the same noise at the identity gives the same estimates times
/// the constant rotation: nothing may break at 180 degrees.
#[test]
fn a_noisy_pose_at_180_degrees_is_estimated_as_anywhere_else() {
    let q180 = UnitQuaternion::from_scaled_axis(Vector3::new(1.0, 2.0, 2.0).normalize() * PI);
    let at = |q0: UnitQuaternion<f64>| move |_: f64| (Vector3::zeros(), q0);
    let samples = measured(&times_30_hz(300), at(q180), 1e-3, 1f64.to_radians(), 3);
    let negative = of_measurements(&samples).filter(|(_, _, q)| q.w < 0.0).count();
    assert!(negative > 50 && negative < 250, "{negative} negative scalar parts");
    let params = PoseSmootherParams::default();
    let out = smooth_poses(&params, &samples).unwrap();
    let (_, angle) = rmse(of_track(&out.smoothed), at(q180));
    let (_, measured_angle) = rmse(of_measurements(&samples), at(q180));
    assert!(angle < 0.5 * measured_angle, "{} deg", angle.to_degrees());
    let at_identity = measured(&times_30_hz(300), at(UnitQuaternion::identity()), 1e-3, 1f64.to_radians(), 3);
    let reference = smooth_poses(&params, &at_identity).unwrap();
    for (a, b) in out.smoothed.iter().zip(&reference.smoothed) {
        assert!(a.orientation.angle_to(&(b.orientation * q180)) < 1e-9);
        assert_relative_eq!(a.covariance, b.covariance, epsilon = 1e-12);
    }
}

/// A smooth (not constant-velocity) motion measured with 1 mm and 1 degree
/// of noise per axis.
fn wavy(t: f64) -> Truth {
    let w = 2.0 * PI;
    let p = Vector3::new(0.02 * (w * 0.3 * t).sin(), 0.01 * (w * 0.2 * t).cos(), 0.4 + 0.005 * t);
    let phi = Vector3::new(0.3 * (w * 0.25 * t).sin(), 0.2 * (w * 0.15 * t + 1.0).sin(), 0.4 * t);
    (p, exp(&phi) * UnitQuaternion::from_euler_angles(0.1, 0.2, 0.3))
}

fn wavy_params() -> PoseSmootherParams {
    PoseSmootherParams {
        q_position_m2_per_s: 1e-9,
        q_velocity_m2_per_s3: 1e-3,
        q_orientation_rad2_per_s: 1e-7,
        q_angular_velocity_rad2_per_s3: 0.3,
        ..PoseSmootherParams::default()
    }
}

/// Catches a smoother that does not smooth (the backward pass skipped or its
/// gain wrong) and an orientation filter that does not use its velocity.
#[test]
fn noisy_poses_are_smoothed_well_below_the_noise() {
    let samples = measured(&times_30_hz(600), wavy, 1e-3, 1f64.to_radians(), 4);
    let out = smooth_poses(&wavy_params(), &samples).unwrap();
    let (mp, mq) = rmse(of_measurements(&samples), wavy);
    let (fp, fq) = rmse(of_track(&out.filtered), wavy);
    let (sp, sq) = rmse(of_track(&out.smoothed), wavy);
    eprintln!(
        "RMSE position (mm): measured {:.3}, filtered {:.3}, smoothed {:.3}; angle (deg): {:.3}, {:.3}, {:.3}",
        mp * 1e3,
        fp * 1e3,
        sp * 1e3,
        mq.to_degrees(),
        fq.to_degrees(),
        sq.to_degrees()
    );
    assert!(sp < 0.5 * mp && sp < fp, "position: smoothed {sp}, filtered {fp}, measured {mp}");
    assert!(sq < 0.5 * mq && sq < fq, "angle: smoothed {sq}, filtered {fq}, measured {mq}");
    assert!(out.measurements.iter().all(|m| matches!(m, MeasurementUse::Accepted { .. })));
}

/// Measurements with random signs (q or -q) give the same estimates.
/// Catches an innovation `q_meas q_pred^-1` whose logarithm does not take
/// the short way (an innovation near 2 pi).
#[test]
fn the_sign_of_a_measured_quaternion_does_not_matter() {
    let samples = measured(&times_30_hz(300), wavy, 1e-3, 1f64.to_radians(), 5);
    let mut flipped = samples.clone();
    let mut rng = ChaCha8Rng::seed_from_u64(6);
    let coin = rand_distr::Bernoulli::new(0.5).unwrap();
    for s in &mut flipped {
        if let Some(m) = s.measurement.as_mut()
            && coin.sample(&mut rng)
        {
            m.orientation = UnitQuaternion::new_unchecked(-m.orientation.into_inner());
        }
    }
    // (nalgebra's `==` on unit quaternions ignores the sign.)
    let w = |s: &PoseSample| s.measurement.map(|m| m.orientation.w);
    let flips = flipped.iter().zip(&samples).filter(|(a, b)| w(a) != w(b)).count();
    assert!(flips > 100, "{flips} flips");
    let params = wavy_params();
    let (a, b) = (smooth_poses(&params, &samples).unwrap(), smooth_poses(&params, &flipped).unwrap());
    for (x, y) in a.smoothed.iter().zip(&b.smoothed).chain(a.filtered.iter().zip(&b.filtered)) {
        assert_relative_eq!(x.position_m, y.position_m, epsilon = 1e-12);
        assert_relative_eq!(x.angular_velocity_rad_per_s, y.angular_velocity_rad_per_s, epsilon = 1e-12);
        assert!(x.orientation.angle_to(&y.orientation) < 1e-12);
        assert_relative_eq!(x.covariance, y.covariance, epsilon = 1e-12);
    }
    assert_eq!(a.measurements, b.measurements);
    assert_relative_eq!(log_likelihood(&params, &samples), log_likelihood(&params, &flipped), epsilon = 1e-9);
}

/// With the orientation at rest, each position axis is
/// [`crate::constant_velocity`] with the same parameters and `x0` at the first
/// measured position: the translation follows the project's conventions
/// (`Q` scaled with `dt`, `F`, the Joseph update, the RTS step).
#[test]
fn the_translation_is_the_1d_smoother_per_axis() {
    let params = PoseSmootherParams { gate: None, ..wavy_params() };
    let still = |t: f64| (wavy(t).0, UnitQuaternion::from_euler_angles(0.3, 0.1, -0.2));
    // Irregular times, some samples without a measurement.
    let times: Vec<f64> = (0..400).map(|k| k as f64 / 30.0 + 0.004 * ((k * 7 % 5) as f64)).collect();
    let mut samples = measured(&times, still, 1e-3, 0.0, 7);
    for s in samples.iter_mut().skip(3).step_by(4) {
        s.measurement = None;
    }
    let out = smooth_poses(&params, &samples).unwrap();
    for axis in 0..3 {
        let cv_samples: Vec<CvSample> = samples
            .iter()
            .map(|s| CvSample { t_s: s.t_s, z_m: s.measurement.map(|m| m.position_m[axis]) })
            .collect();
        let cv = CvParams {
            q_position_m2_per_s: params.q_position_m2_per_s,
            q_velocity_m2_per_s3: params.q_velocity_m2_per_s3,
            r_m2: params.r_position_m2,
            x0: [cv_samples[0].z_m.unwrap(), 0.0],
            p0_diag: [params.p0_position_m2, params.p0_velocity_m2_per_s2],
            gate: None,
        }
        .smooth(&cv_samples)
        .unwrap();
        for (pose, g) in out.smoothed.iter().zip(&cv.smoothed).chain(out.filtered.iter().zip(&cv.filtered)) {
            assert_relative_eq!(pose.position_m[axis], g.mean[0], epsilon = 1e-9);
            assert_relative_eq!(pose.velocity_m_per_s[axis], g.mean[1], epsilon = 1e-9);
            for (a, b) in [(0, 0), (0, 1), (1, 1)] {
                assert_relative_eq!(
                    pose.covariance[(3 * a + axis, 3 * b + axis)],
                    g.cov[(a, b)],
                    max_relative = 1e-9
                );
            }
        }
    }
}

/// A 30-degree flip of the measured orientation (the planar marker's
/// ambiguity) on single frames.
fn flipped_at(samples: &mut [PoseSample], frames: &[usize]) {
    let flip = UnitQuaternion::from_scaled_axis(Vector3::new(1.0, 0.0, 0.0) * 30f64.to_radians());
    for &k in frames {
        if let Some(m) = samples[k].measurement.as_mut() {
            m.orientation = flip * m.orientation;
        }
    }
}

/// The gate rejects the flips, and a rejected pose is exactly a missing one.
/// Without the gate the flips pull the track by degrees (the test can fail).
#[test]
fn single_frame_flips_are_rejected_and_move_nothing() {
    let clean = measured(&times_30_hz(600), wavy, 1e-3, 1f64.to_radians(), 8);
    let frames = [100, 250, 251, 400];
    let mut noisy = clean.clone();
    flipped_at(&mut noisy, &frames);
    let mut dropped = clean.clone();
    for &k in &frames {
        dropped[k].measurement = None;
    }
    let params = wavy_params();
    let (gated, reference) =
        (smooth_poses(&params, &noisy).unwrap(), smooth_poses(&params, &dropped).unwrap());
    for (k, m) in gated.measurements.iter().enumerate() {
        let rejected = matches!(m, MeasurementUse::Rejected { .. });
        assert_eq!(rejected, frames.contains(&k), "sample {k}: {m:?}");
    }
    assert_eq!(gated.smoothed, reference.smoothed);
    let ungated = smooth_poses(&PoseSmootherParams { gate: None, ..params }, &noisy).unwrap();
    let pulled = ungated.smoothed[100].orientation.angle_to(&wavy(ungated.smoothed[100].t_s).1);
    assert!(pulled > 2f64.to_radians(), "{} deg", pulled.to_degrees());
}

/// A real 30-degree turn at 10 s that stays, in a steady rotation, with a
/// model that expects the angular velocity to change little: without
/// re-acquisition the gate locks the filter out for the remaining 10 s (the
/// predicted uncertainty grows too slowly to let the poses in again); with
/// it the track follows (within a degree from 2 s after the jump: the
/// jump jolts the angular velocity, which this model lets change slowly).
#[test]
fn a_real_jump_is_followed_with_reacquisition() {
    let omega = tilted(20.0);
    let jump = UnitQuaternion::from_scaled_axis(Vector3::new(0.0, 1.0, 0.0) * 30f64.to_radians());
    let turned = move |t: f64| {
        let q = exp(&(omega * t));
        (Vector3::zeros(), if t >= 10.0 { jump * q } else { q })
    };
    let samples = measured(&times_30_hz(600), turned, 1e-3, 1f64.to_radians(), 9);
    let error_after = |gate: Gate| {
        let params = PoseSmootherParams {
            q_orientation_rad2_per_s: 1e-8,
            q_angular_velocity_rad2_per_s3: 1e-5,
            gate: Some(gate),
            ..PoseSmootherParams::default()
        };
        let out = smooth_poses(&params, &samples).unwrap();
        let (_, angle) = rmse(of_track(&out.smoothed[360..]), turned);
        angle.to_degrees()
    };
    let locked = error_after(Gate::at(POSE_GATE_MAHALANOBIS2));
    let followed = error_after(Gate { max_mahalanobis2: POSE_GATE_MAHALANOBIS2, reacquire_after: Some(3) });
    eprintln!("after the jump: locked out {locked:.2} deg, re-acquired {followed:.2} deg");
    assert!(locked > 20.0, "{locked} deg");
    assert!(followed < 1.0, "{followed} deg");
}

/// Samples before the first measurement get its estimate; a sequence
/// without measurements gives empty tracks; times must increase.
#[test]
fn starts_gaps_and_bad_times() {
    let mut samples = measured(&times_30_hz(60), wavy, 1e-3, 1f64.to_radians(), 10);
    for s in &mut samples[..4] {
        s.measurement = None;
    }
    let params = PoseSmootherParams::default();
    let out = smooth_poses(&params, &samples).unwrap();
    assert_eq!(out.smoothed.len(), 60);
    for (k, s) in samples.iter().enumerate().take(4) {
        assert_eq!(out.smoothed[k], SmoothedPose { t_s: s.t_s, ..out.smoothed[4] });
        assert_eq!(out.filtered[k], SmoothedPose { t_s: s.t_s, ..out.filtered[4] });
        assert_eq!(out.measurements[k], MeasurementUse::Missing);
    }
    assert!(matches!(out.measurements[4], MeasurementUse::Accepted { mahalanobis2 } if mahalanobis2 < 1e-20));
    let none: Vec<PoseSample> = samples.iter().map(|s| PoseSample { measurement: None, ..*s }).collect();
    assert!(smooth_poses(&params, &none).unwrap().smoothed.is_empty());
    assert!(smooth_poses(&params, &[]).unwrap().smoothed.is_empty());
    assert_eq!(log_likelihood(&params, &none), 0.0);
    let mut bad = samples.clone();
    bad[20].t_s = bad[19].t_s;
    assert_eq!(
        smooth_poses(&params, &bad).unwrap_err(),
        EstimatorError::TimeNotIncreasing { index: 20, t_s: bad[19].t_s }
    );
    assert_eq!(log_likelihood(&params, &bad), f64::NEG_INFINITY);
    bad[20].t_s = f64::NAN;
    assert!(matches!(smooth_poses(&params, &bad), Err(EstimatorError::TimeNotIncreasing { index: 20, .. })));
    let mut nan = samples.clone();
    nan[30].measurement = Some(PoseMeasurement {
        position_m: Vector3::new(f64::NAN, 0.0, 0.0),
        orientation: UnitQuaternion::new_unchecked(Quaternion::identity()),
    });
    assert_eq!(smooth_poses(&params, &nan).unwrap_err(), EstimatorError::NonFiniteMeasurement);
}

/// The likelihood of one pose is the Gaussian of its (zero) innovation with
/// `S = P0 + R`, and of a second the 6-D Gaussian of its innovation.
#[test]
fn the_likelihood_is_the_gaussian_of_the_innovations() {
    let params = PoseSmootherParams { gate: None, ..PoseSmootherParams::default() };
    let z =
        PoseMeasurement { position_m: Vector3::new(0.1, 0.2, 0.3), orientation: UnitQuaternion::identity() };
    let one = [PoseSample { t_s: 0.0, measurement: Some(z) }];
    let (st, sr) = (
        params.p0_position_m2 + params.r_position_m2,
        params.p0_orientation_rad2 + params.r_orientation_rad2,
    );
    let expected = -0.5 * (6.0 * (2.0 * PI).ln() + 3.0 * st.ln() + 3.0 * sr.ln());
    assert_relative_eq!(log_likelihood(&params, &one), expected, epsilon = 1e-12);
    // A second pose at the same place dt later: the prediction is the first
    // posterior, P = (P0^-1 + R^-1)^-1 grown by F and Q(dt).
    let dt = 0.1;
    let y_p = Vector3::new(1e-3, -2e-3, 0.5e-3);
    let y_r = Vector3::new(0.01, 0.0, -0.02);
    let z2 = PoseMeasurement { position_m: z.position_m + y_p, orientation: exp(&y_r) };
    let two = [one[0], PoseSample { t_s: dt, measurement: Some(z2) }];
    let post = |p0: f64, r: f64| p0 * r / (p0 + r);
    let (pp, pv) = (post(params.p0_position_m2, params.r_position_m2), params.p0_velocity_m2_per_s2);
    let s_t = pp + dt * dt * pv + params.q_position_m2_per_s * dt + params.r_position_m2;
    let (rp, rv) =
        (post(params.p0_orientation_rad2, params.r_orientation_rad2), params.p0_angular_velocity_rad2_per_s2);
    let s_r = rp + dt * dt * rv + params.q_orientation_rad2_per_s * dt + params.r_orientation_rad2;
    let second = -0.5
        * (6.0 * (2.0 * PI).ln()
            + 3.0 * s_t.ln()
            + 3.0 * s_r.ln()
            + y_p.norm_squared() / s_t
            + y_r.norm_squared() / s_r);
    assert_relative_eq!(log_likelihood(&params, &two), expected + second, epsilon = 1e-9);
}
