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

mod error;
mod file;
mod fit;
mod map;

#[cfg(test)]
mod file_tests;
#[cfg(test)]
mod tests;

pub use error::LinearMapError;
pub use file::{FORMAT, FORMAT_KEY};
pub use fit::{CvScheme, FitOptions, FitReport};
pub use map::LinearMap;
