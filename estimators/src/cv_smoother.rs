//! The constant-velocity Kalman filter and RTS smoother that turn noisy
//! marker positions into ground truth (thesis Sec. 6.2.3, eqs. 6.12-6.15).
//!
//! State `x = (p, v)` (eq. 6.12): position along the sliding axis (m) and
//! velocity (m/s). Motion (eq. 6.13): `p_k = p_k-1 + v_k-1 dt`, `v_k =
//! v_k-1`, plus `w ~ N(0, Q(dt))`. Measurement (eq. 6.14): `z = p + nu`,
//! `nu ~ N(0, R)`. Samples may come at any times; a sample without a
//! measurement is a predict-only step.
//!
//! # Units and the scaling of `Q` with the step
//! The thesis gives `Q = diag(0.01, 0.01)` per step at the camera's 30 Hz and
//! `R = 10`. Here `Q` is a rate: `Q(dt) = diag(q_p, q_v) * dt` with the
//! spectral densities `q_p` (m^2/s) and `q_v` ((m/s)^2/s) of independent
//! random walks on position and velocity. A process sampled twice as often
//! then gets half the noise per step and the same noise per second, so the
//! smoothing does not depend on the sample rate (100 Hz tactile times with
//! 30 Hz marker measurements in between, or the camera's own times). At
//! `dt = 1/30 s`, `Q(dt) = diag(q_p, q_v) / 30`: the thesis's numbers are
//! `q_p = q_v = 0.3`, `R = 10` in any length unit, because the smoothed mean
//! depends only on the ratios of `Q`, `R` and `P0` (see
//! [`CvSmootherParams::from_per_step`]).
#![expect(non_snake_case, reason = "matrices are named as in the thesis's equations (F, H, Q, R, P, K)")]

use nalgebra::{SMatrix, SVector};

use crate::EstimatorError;
use crate::kf::Gaussian;
use crate::rts::{ForwardFilter, Gate, Measurement, MeasurementUse, Transition, smooth};

/// The parameters of the constant-velocity smoother, in SI units.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CvSmootherParams {
    /// Spectral density of the position random walk, `q_p` (m^2/s).
    pub q_position_m2_per_s: f64,
    /// Spectral density of the velocity random walk, `q_v` ((m/s)^2/s = m^2/s^3).
    pub q_velocity_m2_per_s3: f64,
    /// Variance of one position measurement, `R` (m^2).
    pub r_m2: f64,
    /// Initial state `(p0 (m), v0 (m/s))`, the belief at the first sample
    /// before its measurement.
    pub x0: [f64; 2],
    /// Initial covariance `diag(P0_pp (m^2), P0_vv ((m/s)^2))`.
    pub p0_diag: [f64; 2],
    /// Innovation gate on the marker positions; `None` accepts every one.
    pub gate: Option<Gate>,
}

impl CvSmootherParams {
    /// Parameters from a per-step `Q = diag(q[0], q[1])` and `R` given for
    /// steps of `dt_s` seconds (the thesis: `[0.01, 0.01]`, 10, 1/30 s) and
    /// expressed in a length unit of `unit_m` metres (0.01 for cm). The
    /// returned densities give the same `Q` at `dt_s` steps, in metres.
    pub fn from_per_step(q: [f64; 2], r: f64, dt_s: f64, unit_m: f64) -> CvSmootherParams {
        let u2 = unit_m * unit_m;
        CvSmootherParams {
            q_position_m2_per_s: q[0] * u2 / dt_s,
            q_velocity_m2_per_s3: q[1] * u2 / dt_s,
            r_m2: r * u2,
            ..CvSmootherParams::default()
        }
    }

    /// `F(dt)` (eq. 6.13).
    #[rustfmt::skip]
    pub fn F(dt_s: f64) -> SMatrix<f64, 2, 2> {
        SMatrix::<f64, 2, 2>::new(
            1.0, dt_s,
            0.0, 1.0,
        )
    }

    /// `Q(dt) = diag(q_p, q_v) dt`.
    #[rustfmt::skip]
    pub fn Q(&self, dt_s: f64) -> SMatrix<f64, 2, 2> {
        SMatrix::<f64, 2, 2>::new(
            self.q_position_m2_per_s * dt_s, 0.0,
            0.0,                             self.q_velocity_m2_per_s3 * dt_s,
        )
    }

    /// `H = [1, 0]` (eq. 6.14).
    pub fn H() -> SMatrix<f64, 1, 2> {
        SMatrix::<f64, 1, 2>::new(1.0, 0.0)
    }

    /// `R`.
    pub fn R(&self) -> SMatrix<f64, 1, 1> {
        SMatrix::<f64, 1, 1>::new(self.r_m2)
    }

    /// The belief before the first sample.
    pub fn initial(&self) -> Gaussian<2> {
        let [pp, vv] = self.p0_diag;
        Gaussian::new(SVector::<f64, 2>::from(self.x0), SMatrix::<f64, 2, 2>::new(pp, 0.0, 0.0, vv))
    }

    /// Runs the forward filter and the RTS smoother over `samples` (times
    /// strictly increasing). Fails on a time that does not increase or is
    /// not finite, a non-finite measurement, or singular covariances.
    pub fn run(&self, samples: &[CvSample]) -> Result<CvTrack, EstimatorError> {
        let mut filter = ForwardFilter::new(self.initial()).with_gate(self.gate);
        filter.reserve(samples.len());
        let H = Self::H();
        let R = self.R();
        let mut previous_t_s: Option<f64> = None;
        for (index, sample) in samples.iter().enumerate() {
            let t_s = sample.t_s;
            let transition = match previous_t_s {
                _ if !t_s.is_finite() => return Err(EstimatorError::TimeNotIncreasing { index, t_s }),
                None => Transition::identity(),
                Some(prev) if t_s > prev => {
                    let dt_s = t_s - prev;
                    Transition { F: Self::F(dt_s), Q: self.Q(dt_s) }
                }
                Some(_) => return Err(EstimatorError::TimeNotIncreasing { index, t_s }),
            };
            let measurement = sample.z_m.map(|z| Measurement { z: SVector::<f64, 1>::new(z), H, R });
            filter.step(transition, measurement.as_ref())?;
            previous_t_s = Some(t_s);
        }
        let steps = filter.into_steps();
        let smoothed = smooth(&steps)?;
        Ok(CvTrack {
            filtered: steps.iter().map(|s| s.posterior).collect(),
            measurements: steps.iter().map(|s| s.measurement).collect(),
            smoothed,
        })
    }
}

impl Default for CvSmootherParams {
    /// The thesis's `Q = diag(0.01, 0.01)` per 1/30 s step and `R = 10`,
    /// read in cm: `q_p = 3e-5 m^2/s`, `q_v = 3e-5 m^2/s^3`, `R = 1e-3 m^2`;
    /// the object starts at rest at 0 with `P0 = diag(R, (0.1 m/s)^2)`; no gate.
    fn default() -> Self {
        CvSmootherParams {
            q_position_m2_per_s: 3e-5,
            q_velocity_m2_per_s3: 3e-5,
            r_m2: 1e-3,
            x0: [0.0, 0.0],
            p0_diag: [1e-3, 1e-2],
            gate: None,
        }
    }
}

/// One sample time, with the marker position measured there if any.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CvSample {
    /// Time (s).
    pub t_s: f64,
    /// Measured position (m), `None` for a predict-only step.
    pub z_m: Option<f64>,
}

/// The filter's and the smoother's beliefs at every sample.
#[derive(Clone, Debug, PartialEq)]
pub struct CvTrack {
    /// `p(x_k | z_1:k)`: the Kalman filter's estimate (causal).
    pub filtered: Vec<Gaussian<2>>,
    /// `p(x_k | z_1:T)`: the smoother's estimate, the ground truth (eq. 6.15).
    pub smoothed: Vec<Gaussian<2>>,
    /// What each sample's measurement was used for.
    pub measurements: Vec<MeasurementUse>,
}

#[cfg(test)]
mod tests {
    use approx::assert_relative_eq;

    use super::*;
    use crate::kf::{ConstantVelocity, CovarianceUpdate, predict, update};

    #[test]
    fn the_default_is_the_thesis_model_and_matches_the_smoother_defaults_at_30_hz() {
        let cv = ConstantVelocity::default();
        assert_eq!(cv.Q(), SMatrix::<f64, 2, 2>::new(0.01, 0.0, 0.0, 0.01));
        assert_eq!(cv.R()[(0, 0)], 10.0);
        // The same filter in cm (thesis) and in m (the smoother's SI rates) gives the same track.
        let si = CvSmootherParams::default();
        let (dt, cm) = (1.0 / 30.0, 0.01);
        assert_relative_eq!(si.Q(dt) / (cm * cm), cv.Q(), max_relative = 1e-12);
        assert_relative_eq!(si.r_m2 / (cm * cm), cv.r, max_relative = 1e-12);
    }

    #[test]
    fn the_per_step_thesis_values_map_to_densities_that_give_them_back_at_30_hz() {
        let p = CvSmootherParams::from_per_step([0.01, 0.01], 10.0, 1.0 / 30.0, 0.01);
        let Q = p.Q(1.0 / 30.0);
        assert_relative_eq!(Q[(0, 0)], 0.01 * 1e-4, max_relative = 1e-12);
        assert_relative_eq!(Q[(1, 1)], 0.01 * 1e-4, max_relative = 1e-12);
        assert_relative_eq!(p.r_m2, 10.0 * 1e-4, max_relative = 1e-12);
        let d = CvSmootherParams::default();
        assert_relative_eq!(d.q_position_m2_per_s, p.q_position_m2_per_s, max_relative = 1e-12);
        assert_relative_eq!(d.q_velocity_m2_per_s3, p.q_velocity_m2_per_s3, max_relative = 1e-12);
        assert_relative_eq!(d.r_m2, p.r_m2, max_relative = 1e-12);
    }

    #[test]
    fn the_filtered_track_equals_the_kf_module_step_by_step() {
        let params = CvSmootherParams { gate: None, ..CvSmootherParams::default() };
        let samples: Vec<CvSample> = (0..50)
            .map(|k| CvSample {
                t_s: 0.01 * k as f64,
                z_m: (k % 3 == 0).then(|| 0.002 * k as f64 + 1e-4 * ((k * 7 % 5) as f64 - 2.0)),
            })
            .collect();
        let track = params.run(&samples).unwrap();
        let mut belief = params.initial();
        for (k, s) in samples.iter().enumerate() {
            if k > 0 {
                let dt = s.t_s - samples[k - 1].t_s;
                let cv = ConstantVelocity {
                    q_diag: [params.q_position_m2_per_s * dt, params.q_velocity_m2_per_s3 * dt],
                    r: params.r_m2,
                };
                belief = predict(&belief, &ConstantVelocity::F(dt), &cv.Q());
            }
            if let Some(z) = s.z_m {
                let z = SVector::<f64, 1>::new(z);
                let R = params.R();
                belief = update(&belief, &z, &CvSmootherParams::H(), &R, CovarianceUpdate::Joseph).unwrap().0;
            }
            assert_relative_eq!(track.filtered[k].mean, belief.mean, epsilon = 1e-15);
        }
    }

    #[test]
    fn a_ramp_is_smoothed_to_its_slope_and_missing_samples_are_bridged() {
        let params = CvSmootherParams {
            q_position_m2_per_s: 1e-9,
            q_velocity_m2_per_s3: 1e-6,
            r_m2: 1e-8,
            ..CvSmootherParams::default()
        };
        // 100 Hz samples, a measurement at every third one, 0.02 m/s.
        let samples: Vec<CvSample> = (0..600)
            .map(|k| CvSample { t_s: 0.01 * k as f64, z_m: (k % 3 == 0).then_some(0.02 * 0.01 * k as f64) })
            .collect();
        let track = params.run(&samples).unwrap();
        for (k, s) in track.smoothed.iter().enumerate().skip(30) {
            assert_relative_eq!(s.mean[0], 0.02 * 0.01 * k as f64, epsilon = 1e-6);
            assert_relative_eq!(s.mean[1], 0.02, epsilon = 1e-4);
        }
        assert!(track.measurements.iter().filter(|m| **m == MeasurementUse::Missing).count() == 400);
    }

    #[test]
    fn times_must_increase() {
        let params = CvSmootherParams::default();
        let samples = [CvSample { t_s: 1.0, z_m: None }, CvSample { t_s: 1.0, z_m: Some(0.0) }];
        assert_eq!(
            params.run(&samples).unwrap_err(),
            EstimatorError::TimeNotIncreasing { index: 1, t_s: 1.0 }
        );
        let samples = [CvSample { t_s: f64::NAN, z_m: None }];
        assert!(params.run(&samples).is_err());
        assert!(params.run(&[]).unwrap().smoothed.is_empty());
    }
}
