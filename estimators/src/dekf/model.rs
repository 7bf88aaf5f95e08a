//! A dEKF model: the learned parameters and what is needed to use them.

use nalgebra::DMatrix;
use serde::{Deserialize, Serialize};

use super::ekf::{M2, q_from_cholesky};
use super::params::{Architecture, Layout};
use super::state::StateKind;
use crate::derivative::DerivativeFilterConfig;

/// What the feature network reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Measurement {
    /// The derivative of the baseline-subtracted tactile signal (eq. 6.2).
    Derivative,
    /// The baseline-subtracted signal itself (the ablation of Table 6.3).
    Raw,
}

impl Measurement {
    /// `derivative` or `raw`.
    pub fn name(self) -> &'static str {
        match self {
            Measurement::Derivative => "derivative",
            Measurement::Raw => "raw",
        }
    }
}

/// Everything about a model besides its tensors (the model file's metadata).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ModelMeta {
    /// Time between filter steps, `Delta_t` of (6.3) (s).
    pub dt_s: f64,
    /// The filter steps on every `decimation`-th tactile scan.
    pub decimation: usize,
    /// Tactile scan rate the model was trained at (Hz).
    pub tactile_rate_hz: f64,
    /// Input channels of the feature network, in order (`thumb.x`, ...).
    pub channels: Vec<String>,
    /// What the feature network reads.
    pub measurement: Measurement,
    /// The derivative filter that makes the measurement.
    pub derivative_filter: DerivativeFilterConfig,
    /// The state the model tracks; a file without it holds a sliding model.
    #[serde(default, skip_serializing_if = "StateKind::is_sliding")]
    pub state: StateKind,
    /// Units of the state's components (`cm`, `cm/s` for sliding).
    pub state_units: Vec<String>,
    /// Initial covariance `P0 = diag(..)`, one value per state component
    /// (cm^2, cm^2/s^2; deg^2, deg^2/s^2 for planar rotations).
    pub p0_diag: Vec<f64>,
    /// How the model was trained (configuration, data, losses), free-form JSON.
    pub training: serde_json::Value,
    /// The slidetrack version that wrote the model.
    pub software_version: String,
}

/// A dEKF model.
#[derive(Clone, Debug, PartialEq)]
pub struct DekfModel {
    /// Tensor layout.
    pub layout: Layout,
    /// The flat parameter vector (see [`super::params`]).
    pub params: Vec<f32>,
    /// Metadata.
    pub meta: ModelMeta,
}

impl DekfModel {
    /// A fresh (untrained) model with the thesis's networks.
    pub fn new(meta: ModelMeta, rng: &mut impl rand::Rng) -> DekfModel {
        DekfModel::with_architecture(meta, &Architecture::default(), rng)
    }

    /// A fresh (untrained) model with networks of `arch`, for the state
    /// `meta.state`.
    pub fn with_architecture(meta: ModelMeta, arch: &Architecture, rng: &mut impl rand::Rng) -> DekfModel {
        let layout = Layout::for_state(meta.state, meta.channels.len(), arch);
        let params = layout.init(rng);
        DekfModel { layout, params, meta }
    }

    /// Width, depth and activation of the networks.
    pub fn architecture(&self) -> &Architecture {
        &self.layout.architecture
    }

    /// The state the model tracks.
    pub fn state(&self) -> StateKind {
        self.layout.state
    }

    /// `Q = L_Q L_Q^T` of a sliding model (cm^2, cm^2/s^2).
    pub fn process_noise(&self) -> M2 {
        let o = self.layout.process_noise;
        let p = &self.params;
        q_from_cholesky(f64::from(p[o]), f64::from(p[o + 2]), f64::from(p[o + 3]))
    }

    /// `R = L_R^2` of a sliding model.
    pub fn measurement_noise(&self) -> f64 {
        let l = f64::from(self.params[self.layout.measurement_noise]);
        l * l
    }

    /// The lower-triangular factor stored row-major at `offset`, `k x k`.
    fn cholesky_factor(&self, offset: usize, k: usize) -> DMatrix<f64> {
        DMatrix::from_fn(k, k, |r, c| if c <= r { f64::from(self.params[offset + r * k + c]) } else { 0.0 })
    }

    /// `L_Q` of any state (`2 dofs` square).
    pub fn process_noise_factor(&self) -> DMatrix<f64> {
        let n = self.state().dim();
        self.cholesky_factor(self.layout.process_noise, n)
    }

    /// `L_R` of any state (`dofs` square).
    pub fn measurement_noise_factor(&self) -> DMatrix<f64> {
        let m = self.state().dofs();
        self.cholesky_factor(self.layout.measurement_noise, m)
    }

    /// `Q = L_Q L_Q^T` of any state.
    pub fn process_noise_matrix(&self) -> DMatrix<f64> {
        let l = self.process_noise_factor();
        &l * l.transpose()
    }

    /// `R = L_R L_R^T` of any state.
    pub fn measurement_noise_matrix(&self) -> DMatrix<f64> {
        let l = self.measurement_noise_factor();
        &l * l.transpose()
    }

    /// The feature normalisation: `(mean, std)` per channel.
    pub fn input_normalisation(&self) -> (&[f32], &[f32]) {
        let l = &self.layout;
        (
            &self.params[l.input_mean..l.input_mean + l.channels],
            &self.params[l.input_std..l.input_std + l.channels],
        )
    }

    /// Sets the feature normalisation; a zero or non-finite std becomes 1.
    pub fn set_input_normalisation(&mut self, mean: &[f32], std: &[f32]) {
        let l = self.layout.clone();
        for c in 0..l.channels {
            self.params[l.input_mean + c] = if mean[c].is_finite() { mean[c] } else { 0.0 };
            self.params[l.input_std + c] = if std[c].is_finite() && std[c] > 0.0 { std[c] } else { 1.0 };
        }
    }

    /// Normalises one measurement vector in place: `(x - mean) / std`.
    pub fn normalise(&self, values: &mut [f32]) {
        let (mean, std) = self.input_normalisation();
        for ((v, m), s) in values.iter_mut().zip(mean).zip(std) {
            *v = (*v - m) / s;
        }
    }
}
