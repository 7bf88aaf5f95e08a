//! The derivative of the tactile signal (dEKF table, steps 7-9): one
//! constant-velocity Kalman filter per channel, state `(tau, tau')`, whose
//! velocity component is the derivative.
//!
//! The process noise is the discretised white-noise acceleration model, so
//! its setting does not depend on the sample rate: for a step `dt`,
//! `Q = q [[dt^3/3, dt^2/2], [dt^2/2, dt]]` with `q` in counts^2/s^3; the
//! measurement noise `r` is in counts^2.
#![expect(non_snake_case, reason = "matrices are named as in the thesis's equations (F, H, Q, R, P, K)")]

use nalgebra::{SMatrix, SVector};
use serde::{Deserialize, Serialize};

use crate::kf::{CovarianceUpdate, Gaussian, predict, update};

/// Settings of the derivative filter (stored with every model).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct DerivativeFilterConfig {
    /// Spectral density of the white-noise "acceleration" of the signal (counts^2/s^3).
    pub q_counts2_per_s3: f64,
    /// Measurement noise variance (counts^2).
    pub r_counts2: f64,
    /// Initial variance of the derivative (counts^2/s^2); the value starts at the first sample.
    pub initial_derivative_var: f64,
}

impl Default for DerivativeFilterConfig {
    fn default() -> Self {
        DerivativeFilterConfig { q_counts2_per_s3: 2.0e5, r_counts2: 25.0, initial_derivative_var: 1.0e4 }
    }
}

/// Per-channel derivative filters.
#[derive(Clone, Debug)]
pub struct DerivativeFilter {
    cfg: DerivativeFilterConfig,
    beliefs: Vec<Option<Gaussian<2>>>,
    last_t_s: Option<f64>,
    derivatives: Vec<f64>,
}

impl DerivativeFilter {
    /// Filters for `channels` channels, not started.
    pub fn new(cfg: DerivativeFilterConfig, channels: usize) -> DerivativeFilter {
        DerivativeFilter {
            cfg,
            beliefs: vec![None; channels],
            last_t_s: None,
            derivatives: vec![0.0; channels],
        }
    }

    /// Number of channels filtered.
    pub fn channels(&self) -> usize {
        self.beliefs.len()
    }

    /// The settings.
    pub fn config(&self) -> &DerivativeFilterConfig {
        &self.cfg
    }

    #[rustfmt::skip]
    fn Q(&self, dt: f64) -> SMatrix<f64, 2, 2> {
        let q = self.cfg.q_counts2_per_s3;
        SMatrix::<f64, 2, 2>::new(
            q * dt * dt * dt / 3.0, q * dt * dt / 2.0,
            q * dt * dt / 2.0,      q * dt,
        )
    }

    /// Feeds the values of every channel at time `t_s` (s) and returns the
    /// derivatives (counts/s). A non-finite value is a missing sample for its
    /// channel (prediction only); a channel's derivative is 0 until its
    /// first sample. Times must not go back; equal times repeat the estimate.
    pub fn step(&mut self, t_s: f64, values: &[f64]) -> &[f64] {
        let dt = self.last_t_s.map_or(0.0, |last| (t_s - last).max(0.0));
        self.last_t_s = Some(t_s);
        let F = SMatrix::<f64, 2, 2>::new(1.0, dt, 0.0, 1.0);
        let Q = self.Q(dt);
        let H = SMatrix::<f64, 1, 2>::new(1.0, 0.0);
        let R = SMatrix::<f64, 1, 1>::new(self.cfg.r_counts2);
        for ((belief, value), out) in self.beliefs.iter_mut().zip(values).zip(self.derivatives.iter_mut()) {
            match belief {
                None if value.is_finite() => {
                    let cov = SMatrix::<f64, 2, 2>::new(
                        self.cfg.r_counts2,
                        0.0,
                        0.0,
                        self.cfg.initial_derivative_var,
                    );
                    *belief = Some(Gaussian::new(SVector::<f64, 2>::new(*value, 0.0), cov));
                }
                None => {}
                Some(b) => {
                    let prior = predict(b, &F, &Q);
                    *b = if value.is_finite() {
                        let z = SVector::<f64, 1>::new(*value);
                        update(&prior, &z, &H, &R, CovarianceUpdate::Joseph).map_or(prior, |(post, _)| post)
                    } else {
                        prior
                    };
                }
            }
            *out = belief.map_or(0.0, |b| b.mean[1]);
        }
        &self.derivatives
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_ramp_gives_its_slope_and_a_constant_gives_zero() {
        let mut f = DerivativeFilter::new(DerivativeFilterConfig::default(), 2);
        let mut last = [0.0, 0.0];
        for k in 0..300 {
            let t = k as f64 * 0.01;
            let d = f.step(t, &[1000.0 + 250.0 * t, 31000.0]);
            last = [d[0], d[1]];
        }
        assert!((last[0] - 250.0).abs() < 1.0, "{}", last[0]);
        assert!(last[1].abs() < 1e-6, "{}", last[1]);
    }

    #[test]
    fn missing_samples_predict_and_never_produce_nan() {
        let mut f = DerivativeFilter::new(DerivativeFilterConfig::default(), 1);
        for k in 0..100 {
            let t = k as f64 * 0.01;
            let v = if k % 7 == 3 { f64::NAN } else { 100.0 * t };
            let d = f.step(t, &[v]);
            assert!(d[0].is_finite());
        }
        assert_eq!(
            DerivativeFilter::new(DerivativeFilterConfig::default(), 1).step(0.0, &[f64::NAN]),
            &[0.0]
        );
    }
}
