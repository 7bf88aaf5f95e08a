#![expect(non_snake_case, reason = "matrices are named as in the thesis's equations (F, H, Q, R, P, K)")]

use approx::assert_relative_eq;
use nalgebra::{SMatrix, SVector};

use super::expanded::ExpandedBelief;
use super::*;
use crate::EstimatorError;
use crate::kf::{CovarianceUpdate, predict, update};
use crate::rts::{Gate, MeasurementUse};

/// The labelling's default parameters (`slidetrack_calibration`'s
/// `default_params`): 0.5 mm marker noise, a gate at 5 sigma.
fn labelling() -> CvParams {
    CvParams {
        q_position_m2_per_s: 1e-8,
        q_velocity_m2_per_s3: 1e-4,
        r_m2: 2.5e-7,
        x0: [0.0, 0.0],
        p0_diag: [2.5e-7, 1e-4],
        gate: Some(Gate::at(25.0)),
    }
}

/// 50 samples at 100 Hz, a slow slide measured at every third one.
fn slide() -> Vec<CvSample> {
    (0..50)
        .map(|k| CvSample {
            t_s: 0.01 * k as f64,
            z_m: (k % 3 == 0).then(|| 0.002 * k as f64 + 1e-4 * ((k * 7 % 5) as f64 - 2.0)),
        })
        .collect()
}

#[test]
fn the_default_is_the_thesis_model_per_30_hz_step_read_in_cm() {
    let si = CvParams::default();
    let (dt, cm) = (1.0 / 30.0, 0.01);
    let thesis_Q = SMatrix::<f64, 2, 2>::new(0.01, 0.0, 0.0, 0.01);
    assert_relative_eq!(si.Q(dt) / (cm * cm), thesis_Q, max_relative = 1e-12);
    assert_relative_eq!(si.r_m2 / (cm * cm), 10.0, max_relative = 1e-12);
}

#[test]
fn the_per_step_thesis_values_map_to_densities_that_give_them_back_at_30_hz() {
    let p = CvParams::from_per_step([0.01, 0.01], 10.0, 1.0 / 30.0, 0.01);
    let Q = p.Q(1.0 / 30.0);
    assert_relative_eq!(Q[(0, 0)], 0.01 * 1e-4, max_relative = 1e-12);
    assert_relative_eq!(Q[(1, 1)], 0.01 * 1e-4, max_relative = 1e-12);
    assert_relative_eq!(p.r_m2, 10.0 * 1e-4, max_relative = 1e-12);
    let d = CvParams::default();
    assert_relative_eq!(d.q_position_m2_per_s, p.q_position_m2_per_s, max_relative = 1e-12);
    assert_relative_eq!(d.q_velocity_m2_per_s3, p.q_velocity_m2_per_s3, max_relative = 1e-12);
    assert_relative_eq!(d.r_m2, p.r_m2, max_relative = 1e-12);
}

#[test]
fn the_smoothers_filtered_track_is_the_kalman_filter_step_by_step() {
    let params = CvParams { gate: None, ..CvParams::default() };
    let samples = slide();
    let track = params.smooth(&samples).unwrap();
    let mut belief = params.initial();
    for (k, s) in samples.iter().enumerate() {
        if k > 0 {
            let dt = s.t_s - samples[k - 1].t_s;
            belief = predict(&belief, &CvParams::F(dt), &params.Q(dt));
        }
        if let Some(z) = s.z_m {
            let z = SVector::<f64, 1>::new(z);
            belief = update(&belief, &z, &CvParams::H(), &params.R(), CovarianceUpdate::Joseph).unwrap().0;
        }
        assert_relative_eq!(track.filtered[k].mean, belief.mean, epsilon = 1e-15);
    }
}

#[test]
fn the_causal_filter_is_the_smoothers_forward_pass_from_the_first_measurement() {
    let params = labelling();
    let samples = slide();
    let track = params.smooth(&samples).unwrap();
    let mut filter = CvFilter::new(params);
    for (k, s) in samples.iter().enumerate() {
        let belief = filter.step(s.t_s, s.z_m).expect("the first sample is measured");
        assert_eq!(belief, track.filtered[k], "sample {k}");
    }
}

#[test]
fn the_expanded_form_is_the_matrix_form() {
    let params = CvParams { gate: None, ..labelling() };
    let samples = slide();
    let mut expanded = ExpandedBelief::initial(&params);
    let mut belief = params.initial();
    for (k, s) in samples.iter().enumerate() {
        if k > 0 {
            let dt = s.t_s - samples[k - 1].t_s;
            expanded.predict(&params, dt);
            let t = params.transition(dt);
            belief = predict(&belief, &t.F, &t.Q);
        }
        if let Some(z) = s.z_m {
            let (nu, s_m2) = expanded.innovation(&params, z);
            let m = params.measurement(z);
            let (posterior, innovation) =
                update(&belief, &m.z, &m.H, &m.R, CovarianceUpdate::Simple).unwrap();
            assert_relative_eq!(nu, innovation.residual[0], max_relative = 1e-12);
            assert_relative_eq!(s_m2, innovation.cov[(0, 0)], max_relative = 1e-12);
            expanded.correct(nu, s_m2);
            belief = posterior;
        }
        let x = SVector::<f64, 2>::from(expanded.x);
        let P =
            SMatrix::<f64, 2, 2>::new(expanded.p[0][0], expanded.p[0][1], expanded.p[1][0], expanded.p[1][1]);
        assert_relative_eq!(x, belief.mean, epsilon = 1e-15, max_relative = 1e-12);
        assert_relative_eq!(P, belief.cov, epsilon = 1e-20, max_relative = 1e-9);
    }
}

#[test]
fn a_ramp_is_smoothed_to_its_slope_and_missing_samples_are_bridged() {
    let params =
        CvParams { q_position_m2_per_s: 1e-9, q_velocity_m2_per_s3: 1e-6, r_m2: 1e-8, ..CvParams::default() };
    // 100 Hz samples, a measurement at every third one, 0.02 m/s.
    let samples: Vec<CvSample> = (0..600)
        .map(|k| CvSample { t_s: 0.01 * k as f64, z_m: (k % 3 == 0).then_some(0.02 * 0.01 * k as f64) })
        .collect();
    let track = params.smooth(&samples).unwrap();
    for (k, s) in track.smoothed.iter().enumerate().skip(30) {
        assert_relative_eq!(s.mean[0], 0.02 * 0.01 * k as f64, epsilon = 1e-6);
        assert_relative_eq!(s.mean[1], 0.02, epsilon = 1e-4);
    }
    assert!(track.measurements.iter().filter(|m| **m == MeasurementUse::Missing).count() == 400);
}

#[test]
fn the_smoothers_times_must_increase() {
    let params = CvParams::default();
    let samples = [CvSample { t_s: 1.0, z_m: None }, CvSample { t_s: 1.0, z_m: Some(0.0) }];
    assert_eq!(
        params.smooth(&samples).unwrap_err(),
        EstimatorError::TimeNotIncreasing { index: 1, t_s: 1.0 }
    );
    let samples = [CvSample { t_s: f64::NAN, z_m: None }];
    assert!(params.smooth(&samples).is_err());
    assert!(params.smooth(&[]).unwrap().smoothed.is_empty());
}

#[test]
fn without_noise_the_causal_filter_extrapolates_exactly() {
    let params = CvParams {
        q_position_m2_per_s: 0.0,
        q_velocity_m2_per_s3: 0.0,
        r_m2: 1.0,
        x0: [1.0, 2.0],
        p0_diag: [0.0, 0.0],
        gate: None,
    };
    let mut f = CvFilter::new(params);
    let mut b = f.step(0.0, Some(1.0)).expect("measured");
    for k in 1..=10 {
        b = f.step(0.1 * k as f64, None).expect("started");
    }
    assert_relative_eq!(b.mean[0], 3.0, epsilon = 1e-12);
    assert_relative_eq!(b.mean[1], 2.0, epsilon = 1e-12);
}

#[test]
fn the_causal_filter_starts_at_the_first_measurement_and_follows_a_constant_velocity() {
    let mut f = CvFilter::new(CvParams { gate: None, ..labelling() });
    assert!(f.step(0.0, None).is_none(), "nothing before the first measurement");
    assert!(f.step(0.01, Some(f64::NAN)).is_none(), "a NaN is no measurement");
    let mut last = None;
    for k in 1..300 {
        let t = k as f64 / 30.0;
        // 1 cm/s, one frame in five missed.
        let z = (k % 5 != 0).then_some(0.01 * t);
        last = f.step(t, z);
    }
    let b = last.expect("a belief after the first measurement");
    assert!((b.mean[1] - 0.01).abs() < 5e-4, "velocity {}", b.mean[1]);
    assert!((b.mean[0] - 0.01 * 299.0 / 30.0).abs() < 5e-4, "position {}", b.mean[0]);
}

#[test]
fn the_causal_filter_rejects_an_outlier_and_predicts_through_nan() {
    let mut f = CvFilter::new(labelling());
    for k in 0..60 {
        f.step(k as f64 / 30.0, Some(0.0));
    }
    let jump = f.step(2.0, Some(0.05)).expect("belief");
    assert!(jump.mean[0].abs() < 1e-4, "a 5 cm jump is an outlier: {}", jump.mean[0]);
    let mut g = f;
    let nan = f.step(2.1, Some(f64::NAN)).expect("belief");
    assert!(nan.mean.iter().all(|x| x.is_finite()));
    assert_eq!(Some(nan), g.step(2.1, None), "a NaN is a missing measurement");
}
