//! The linear baseline: a ridge-regression map from the same input channels
//! to the same outputs as a learned tracker, fitted on the same training
//! sessions. A learned tracker earns its complexity only by beating it.
//!
//! # Equations
//!
//! Inputs are standardised and outputs centred with the statistics of the
//! training rows (population standard deviation; a constant input gets
//! `σ = 1`, so it stays near zero and contributes nothing):
//!
//! ```text
//! z_i = (x_i − μ_i) / σ_i          ỹ_o = y_o − ȳ_o
//! ```
//!
//! The intercept is thus not penalised. Each output `o` has its own ridge
//! penalty `λ_o` and weights
//!
//! ```text
//! w_o = argmin ‖Z w − ỹ_o‖² + λ_o ‖w‖² = (ZᵀZ + λ_o I)⁻¹ Zᵀ ỹ_o
//! ```
//!
//! solved through one eigendecomposition `ZᵀZ = V D Vᵀ` that serves every
//! penalty: `w_o = V (D + λ_o I)⁻¹ Vᵀ Zᵀ ỹ_o`. `λ > 0` makes this well
//! defined with more inputs than rows, constant or collinear inputs.
//! The map applied is `y = ȳ + W z`, or in the original input units
//! `y = W' x + b` with `W' = W diag(1/σ)` and `b = ȳ − W' μ` (what the file's
//! `linear.weight` and `linear.bias` hold).
//!
//! # Choice of the penalty
//!
//! `λ_o` is picked per output among [`FitOptions::lambdas`] by the smallest
//! cross-validated mean squared error of that output. Per output because the
//! outputs are in different units (cm, deg, cm/s) and differ in how much of
//! them the inputs explain: one shared penalty would be decided by whichever
//! output has the largest numbers. The choice does not depend on the outputs'
//! units. The folds are grouped by the rows' group (the session), see
//! [`CvScheme`]: rows of one session are neighbours in time and nearly
//! repeat each other, and held out only together does the error measure
//! prediction on an unseen session.
//!
//! # File
//!
//! [`LinearMap::to_bytes`] writes safetensors, all tensors `F64`, matrices
//! row-major:
//!
//! | tensor                | shape               | holds                                    |
//! |-----------------------|---------------------|------------------------------------------|
//! | `linear.weight`       | `[outputs, inputs]` | `W'`: `y = W' x + b` in the input units  |
//! | `linear.bias`         | `[outputs]`         | `b`                                      |
//! | `standardised.weight` | `[outputs, inputs]` | `W`, on standardised inputs (as fitted)  |
//! | `input_mean`          | `[inputs]`          | `μ`                                      |
//! | `input_std`           | `[inputs]`          | `σ`, positive                            |
//! | `output_mean`         | `[outputs]`         | `ȳ`                                      |
//!
//! Any tool can apply `linear.*` alone. `standardised.weight` is what
//! slidetrack applies, kept so that a map read back is the map written, bit
//! for bit (`W'·σ` need not round back to `W`); reading checks that the two
//! agree (to 1e-9). Header metadata, all JSON strings: [`FORMAT_KEY`]
//! (= [`FORMAT`]), `input_names` and `output_names` (arrays of strings),
//! `lambda` (array, one penalty per output), `meta` (any JSON). The header's
//! keys are sorted, so the same map gives the same bytes.

mod file;
mod fit;

#[cfg(test)]
mod file_tests;
#[cfg(test)]
mod tests;

use nalgebra::{DMatrix, DVector};
use thiserror::Error;

pub use file::{FORMAT, FORMAT_KEY};
pub use fit::{CvScheme, FitReport};

/// A fitted linear map from input channels to outputs.
#[derive(Clone, Debug, PartialEq)]
pub struct LinearMap {
    /// Names of the input channels, in the order [`LinearMap::apply`] reads them.
    pub input_names: Vec<String>,
    /// Names of the outputs (with units, e.g. `position_cm`), in the order written.
    pub output_names: Vec<String>,
    /// Mean `μ` of each input over the training rows.
    pub input_mean: Vec<f64>,
    /// Population standard deviation `σ` of each input over the training
    /// rows; 1 for a constant input. Always positive.
    pub input_std: Vec<f64>,
    /// Mean `ȳ` of each output over the training rows.
    pub output_mean: Vec<f64>,
    /// `W`, `[outputs, inputs]`: the weights on standardised inputs.
    pub weights: DMatrix<f64>,
    /// The ridge penalty `λ_o` chosen for each output.
    pub lambda: Vec<f64>,
    /// Free-form: what the map was fitted on, its cross-validation scores, ...
    /// [`LinearMap::fit`] stores its [`FitReport`] under `"fit"`.
    pub meta: serde_json::Value,
}

/// Options of [`LinearMap::fit`].
#[derive(Clone, Debug, PartialEq)]
pub struct FitOptions {
    /// Candidate penalties, each finite and positive (order and repeats do
    /// not matter). Default: 33 values log-spaced from 1e-3 to 1e5, four per
    /// decade.
    pub lambdas: Vec<f64>,
    /// Number of cross-validation folds, at least 2. Default 5.
    pub folds: usize,
}

impl Default for FitOptions {
    fn default() -> Self {
        FitOptions { lambdas: (-12..=20).map(|k| 10f64.powf(f64::from(k) / 4.0)).collect(), folds: 5 }
    }
}

/// Why a map could not be fitted or read.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum LinearMapError {
    /// No rows were given.
    #[error("no rows to fit")]
    NoRows,
    /// A map needs at least one input and one output.
    #[error("no {what} channels")]
    NoChannels {
        /// `"input"` or `"output"`.
        what: &'static str,
    },
    /// Two channels have the same name.
    #[error("{what} channel `{name}` appears twice")]
    DuplicateName {
        /// `"input"` or `"output"`.
        what: &'static str,
        /// The name.
        name: String,
    },
    /// A slice has the wrong length for the number of rows and channels.
    #[error("{what}: expected {expected} values, got {got}")]
    WidthMismatch {
        /// Which slice.
        what: &'static str,
        /// Its length for the rows and channels given.
        expected: usize,
        /// Its length.
        got: usize,
    },
    /// Every row holds a non-finite input or output.
    #[error("all {rows} rows hold a non-finite input or output")]
    AllRowsNonFinite {
        /// Rows given.
        rows: usize,
    },
    /// The options cannot be used.
    #[error("fit options: {detail}")]
    BadOptions {
        /// What is wrong.
        detail: String,
    },
    /// Values so large that their statistics overflow.
    #[error("{what} {index}: its mean or spread is not finite (values too large)")]
    Overflow {
        /// `"input"` or `"output"`.
        what: &'static str,
        /// The channel.
        index: usize,
    },
    /// The eigendecomposition of `ZᵀZ` did not converge.
    #[error("the eigendecomposition of the {size}x{size} Gram matrix did not converge")]
    Decomposition {
        /// Number of inputs.
        size: usize,
    },
    /// Not a valid safetensors file, or a corrupt one.
    #[error("not a valid safetensors file: {0}")]
    Safetensors(#[from] safetensors::SafeTensorError),
    /// A metadata entry is missing or wrong.
    #[error("metadata `{key}`: {detail}")]
    Metadata {
        /// The key.
        key: &'static str,
        /// What is wrong.
        detail: String,
    },
    /// A tensor is missing or has the wrong type, shape or values.
    #[error("tensor `{name}`: {detail}")]
    Tensor {
        /// The tensor.
        name: &'static str,
        /// What is wrong.
        detail: String,
    },
}

impl LinearMap {
    /// Number of input channels.
    pub fn inputs(&self) -> usize {
        self.input_names.len()
    }

    /// Number of outputs.
    pub fn outputs(&self) -> usize {
        self.output_names.len()
    }

    /// `y = ȳ + W (x − μ)/σ` for one sample. Allocation-free. An input that
    /// is NaN or infinite makes every output NaN.
    ///
    /// # Panics
    /// If `input` or `output` does not have the map's width (a caller bug).
    pub fn apply(&self, input: &[f64], output: &mut [f64]) {
        assert_eq!(input.len(), self.inputs(), "LinearMap::apply: input width");
        assert_eq!(output.len(), self.outputs(), "LinearMap::apply: output width");
        if input.iter().any(|x| !x.is_finite()) {
            output.fill(f64::NAN);
            return;
        }
        for (o, y) in output.iter_mut().enumerate() {
            let mut sum = 0.0;
            for (i, x) in input.iter().enumerate() {
                sum += self.weights[(o, i)] * ((x - self.input_mean[i]) / self.input_std[i]);
            }
            *y = self.output_mean[o] + sum;
        }
    }

    /// The map in the original input units, `y = W' x + b`: `W'`
    /// `[outputs, inputs]` and `b` `[outputs]` (what the file stores as
    /// `linear.weight` and `linear.bias`).
    pub fn affine(&self) -> (DMatrix<f64>, DVector<f64>) {
        let w =
            DMatrix::from_fn(self.outputs(), self.inputs(), |o, i| self.weights[(o, i)] / self.input_std[i]);
        let b = DVector::from_fn(self.outputs(), |o, _| {
            let shift: f64 = (0..self.inputs()).map(|i| w[(o, i)] * self.input_mean[i]).sum();
            self.output_mean[o] - shift
        });
        (w, b)
    }
}
