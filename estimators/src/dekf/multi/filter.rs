//! The vector dEKF running online or on replay: one prediction and
//! correction per filter step, the networks evaluated on the single sample
//! with their Jacobians as tangent columns (the batched path of training,
//! so the two cannot disagree).
#![expect(non_snake_case, reason = "matrices are named as in the thesis's equations (F, H, Q, R, P)")]

use nalgebra::DMatrix;

use super::bptt::{Noise, value_and_jacobian, with_tangents};
use super::ekf::{Mat, Vect, correct, predict};
use crate::dekf::mlp::forward;
use crate::dekf::model::DekfModel;
use crate::dekf::params::Layout;

/// The filter of a model with `N = 2 M` state components.
pub struct MultiFilter<const N: usize, const M: usize> {
    params: Vec<f32>,
    layout: Layout,
    noise: Noise<N, M>,
    dt: f64,
    norm_mean: Vec<f32>,
    norm_std: Vec<f32>,
    P0: Mat<N, N>,
    mean: Vect<N>,
    cov: Mat<N, N>,
}

impl<const N: usize, const M: usize> MultiFilter<N, M> {
    /// The filter of `model` at `mu0 = 0`, `P0` from the model.
    pub fn new(model: &DekfModel) -> MultiFilter<N, M> {
        let (m, s) = model.input_normalisation();
        let P0 = Mat::<N, N>::from_fn(|r, c| if r == c { model.meta.p0_diag[r] } else { 0.0 });
        MultiFilter {
            params: model.params.clone(),
            layout: model.layout.clone(),
            noise: Noise::of(model),
            dt: model.meta.dt_s,
            norm_mean: m.to_vec(),
            norm_std: s.to_vec(),
            P0,
            mean: Vect::zeros(),
            cov: P0,
        }
    }

    /// The mean and the covariance (row-major).
    pub fn state(&self) -> (Vec<f64>, Vec<f64>) {
        (self.mean.as_slice().to_vec(), self.cov.transpose().as_slice().to_vec())
    }

    /// One prediction and, when the measurement (unnormalised, model channel
    /// order) is finite and usable, one correction. Returns whether it corrected.
    pub fn step(&mut self, measurement: &[f64]) -> bool {
        let (p, l, cols) = (&self.params, &self.layout, N + 1);
        let (y1, _) = forward(p, &l.motion, with_tangents(&[self.mean]), cols, false);
        let (a, J1) = value_and_jacobian::<N, M>(&y1, 0);
        let pred = predict(&self.mean, &self.cov, &a, &J1, self.dt, &self.noise.Q);
        self.mean = pred.mean;
        self.cov = pred.cov;
        if !measurement.iter().all(|v| v.is_finite()) {
            return false;
        }
        let x3 = DMatrix::<f32>::from_iterator(
            measurement.len(),
            1,
            measurement.iter().enumerate().map(|(c, v)| (*v as f32 - self.norm_mean[c]) / self.norm_std[c]),
        );
        let (y3, _) = forward(p, &l.feature, x3, 1, false);
        let z = Vect::<M>::from_fn(|i, _| f64::from(y3[(i, 0)]));
        let (y2, _) = forward(p, &l.measurement, with_tangents(&[pred.mean]), cols, false);
        let (zhat, H) = value_and_jacobian::<N, M>(&y2, 0);
        let Some(c) = correct(&pred.mean, &pred.cov, &z, &zhat, &H, &self.noise.R) else { return false };
        if !c.mean.iter().chain(c.cov.iter()).all(|v| v.is_finite()) {
            return false;
        }
        self.mean = c.mean;
        self.cov = c.cov;
        true
    }

    /// Back to `mu0 = 0`, `P0`.
    pub fn reset(&mut self) {
        self.mean = Vect::zeros();
        self.cov = self.P0;
    }
}
