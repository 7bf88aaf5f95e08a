//! Tactile counts to newtons: a per-taxel map from tared counts to the
//! force on the taxel (N, per axis, with cross-talk), fitted by least
//! squares against a reference force, stored as a versioned TOML file.
//!
//! The map of one taxel is `F = offset + M c (+ Q q(c))`: `c` the taxel's
//! counts minus its no-contact baseline (as XELA's tools tare), `M` a 3x3
//! matrix (the diagonal the gains, the rest the cross-talk between axes),
//! and, in the `quadratic` model, `q(c)` the six second-order terms
//! `[cx², cy², cz², cx cy, cx cz, cy cz]` for the magnet's nonlinear
//! response. XELA's own calibration (omron-sinicx/xela_server_ros,
//! `scripts/calibrate_digital_to_force.py`) is one slope and intercept per
//! axis for the sum of a sensor's taxels, shared by every taxel; see
//! `docs/tactile-calibration.md`.

mod error;
mod eval;
mod features;
mod file;
mod fit;
#[cfg(test)]
mod tests;

pub use error::TactileForceError;
pub use eval::{AxisErrors, AxisSlopes, axis_errors, fit_axis_slopes, fit_global_scale};
pub use features::{ForceModelKind, TaxelForceMap};
pub use file::{FORMAT, SensorForceMap, TactileForceCalibration, VERSION};
pub use fit::{TaxelFit, fit_taxel};
