//! The derivative of the tactile signal (dEKF table, steps 7-9): one
//! constant-velocity Kalman filter per channel, state `(tau, tau')`, whose
//! velocity component is the derivative.
//!
//! The process noise is the discretised white-noise acceleration model, so
//! its setting does not depend on the sample rate: for a step `dt`,
//! `Q = q [[dt^3/3, dt^2/2], [dt^2/2, dt]]` with `q` in counts^2/s^3; the
//! measurement noise `r` is in counts^2.
//!
//! An isolated spike (a single wild sample, as tactile sensors produce now
//! and then) would pass straight into the derivative, and through the
//! dEKF's measurement into its velocity. The filter gates it: a sample whose
//! innovation exceeds `outlier_gate_sigma` standard deviations of its
//! predicted distribution is left out (a prediction-only step), for at most
//! `max_outlier_scans` scans in a row; a sample still that far after them
//! means the signal really moved (contact, a slip), and the channel's filter
//! starts again from it.
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
    /// Innovation gate (standard deviations of the predicted sample): a
    /// sample further than this from its prediction is an outlier and left
    /// out. 0 turns the gate off; a model file without this field (written
    /// before the gate) has it off.
    #[serde(default)]
    pub outlier_gate_sigma: f64,
    /// Most scans in a row one channel may leave out; the next is taken
    /// whatever its innovation.
    #[serde(default = "default_max_outlier_scans")]
    pub max_outlier_scans: u32,
}

/// Outliers left out in a row, at most: tactile spikes last one sample.
fn default_max_outlier_scans() -> u32 {
    2
}

impl Default for DerivativeFilterConfig {
    fn default() -> Self {
        DerivativeFilterConfig {
            q_counts2_per_s3: 2.0e5,
            r_counts2: 25.0,
            initial_derivative_var: 1.0e4,
            outlier_gate_sigma: DEFAULT_OUTLIER_GATE_SIGMA,
            max_outlier_scans: default_max_outlier_scans(),
        }
    }
}

/// The gate of new models (standard deviations).
pub const DEFAULT_OUTLIER_GATE_SIGMA: f64 = 8.0;

/// Per-channel derivative filters.
#[derive(Clone, Debug)]
pub struct DerivativeFilter {
    cfg: DerivativeFilterConfig,
    beliefs: Vec<Option<Gaussian<2>>>,
    /// Outliers each channel has left out in a row.
    left_out: Vec<u32>,
    /// Outliers left out so far, all channels.
    outliers: u64,
    last_t_s: Option<f64>,
    derivatives: Vec<f64>,
}

impl DerivativeFilter {
    /// Filters for `channels` channels, not started.
    pub fn new(cfg: DerivativeFilterConfig, channels: usize) -> DerivativeFilter {
        DerivativeFilter {
            cfg,
            beliefs: vec![None; channels],
            left_out: vec![0; channels],
            outliers: 0,
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

    /// Samples the gate has left out so far, all channels.
    pub fn outliers(&self) -> u64 {
        self.outliers
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
        let gate = self.cfg.outlier_gate_sigma;
        let initial_cov =
            SMatrix::<f64, 2, 2>::new(self.cfg.r_counts2, 0.0, 0.0, self.cfg.initial_derivative_var);
        let channels =
            self.beliefs.iter_mut().zip(&mut self.left_out).zip(values).zip(self.derivatives.iter_mut());
        // The belief of a channel starting at `value`: the value itself, no derivative yet.
        let start = |value: f64| Gaussian::new(SVector::<f64, 2>::new(value, 0.0), initial_cov);
        for (((belief, left_out), value), out) in channels {
            match belief {
                None if value.is_finite() => *belief = Some(start(*value)),
                None => {}
                Some(b) => {
                    let prior = predict(b, &F, &Q);
                    // Squared innovation against gate^2 times its variance.
                    let innovation = value - prior.mean[0];
                    let variance = prior.cov[(0, 0)] + self.cfg.r_counts2;
                    let outlier = gate > 0.0 && innovation * innovation > gate * gate * variance;
                    *b = if !value.is_finite() {
                        prior
                    } else if outlier && *left_out < self.cfg.max_outlier_scans {
                        *left_out += 1;
                        self.outliers += 1;
                        prior
                    } else if outlier {
                        // Still far after the outliers allowed: the signal
                        // moved for real; start again from this sample.
                        *left_out = 0;
                        start(*value)
                    } else {
                        *left_out = 0;
                        let z = SVector::<f64, 1>::new(*value);
                        update(&prior, &z, &H, &R, CovarianceUpdate::Joseph).map_or(prior, |(post, _)| post)
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

    /// A noisy ramp at 100 Hz with a one-sample spike of `spike` counts at
    /// scan 150; the largest error of the derivative from the slope after
    /// settling, and the samples left out.
    fn worst_derivative_error(cfg: DerivativeFilterConfig, spike: f64) -> (f64, u64) {
        let mut f = DerivativeFilter::new(cfg, 1);
        let mut worst: f64 = 0.0;
        for k in 0..300 {
            let t = k as f64 * 0.01;
            // Deterministic noise of about 3 counts.
            let noise = 3.0 * ((k * 7919 % 13) as f64 / 6.0 - 1.0);
            let v = 1000.0 + 250.0 * t + noise + if k == 150 { spike } else { 0.0 };
            let d = f.step(t, &[v])[0];
            if k > 100 {
                worst = worst.max((d - 250.0).abs());
            }
        }
        (worst, f.outliers())
    }

    #[test]
    fn an_isolated_spike_is_left_out_and_a_real_step_is_followed() {
        let gated = DerivativeFilterConfig::default();
        let open = DerivativeFilterConfig { outlier_gate_sigma: 0.0, ..gated };
        // Without the gate a 1500-count spike throws the derivative far off.
        let (spiked, _) = worst_derivative_error(open, 1500.0);
        assert!(spiked > 5000.0, "{spiked}");
        // With it the derivative does not notice (noise alone: some tens of counts/s).
        let (quiet, _) = worst_derivative_error(open, 0.0);
        let (gated_error, left_out) = worst_derivative_error(gated, 1500.0);
        assert_eq!(left_out, 1);
        assert!(gated_error <= quiet + 1.0, "{gated_error} vs {quiet} without a spike");
        // A step that stays is followed after max_outlier_scans scans: the
        // filter ends up on the new level, not stuck on the old one.
        let mut f = DerivativeFilter::new(gated, 1);
        let mut last = 0.0;
        for k in 0..200 {
            let v = if k < 100 { 1000.0 } else { 3000.0 };
            f.step(k as f64 * 0.01, &[v]);
            last = f.beliefs[0].map_or(0.0, |b| b.mean[0]);
        }
        assert_eq!(f.outliers(), u64::from(gated.max_outlier_scans));
        assert!((last - 3000.0).abs() < 1.0, "{last}");
    }

    #[test]
    fn a_model_file_without_the_gate_runs_without_it() {
        let old: DerivativeFilterConfig = serde_json::from_str(
            r#"{"q_counts2_per_s3": 2e5, "r_counts2": 25.0, "initial_derivative_var": 1e4}"#,
        )
        .expect("old settings");
        assert_eq!(old.outlier_gate_sigma, 0.0);
        let new = DerivativeFilterConfig::default();
        let back: DerivativeFilterConfig =
            serde_json::from_str(&serde_json::to_string(&new).expect("json")).expect("read back");
        assert_eq!(back, new);
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
