//! `slidetrack calibrate tactile`: tactile counts to newtons. Reads tared
//! counts and reference forces from sessions, fits a map per taxel
//! (`slidetrack_calibration::tactile_force`), measures it on held-out
//! sessions beside the trivial maps, writes the calibration file, and adds
//! `/tactile/calibrated` to a finished session. The online path is
//! [`crate::observer::SessionObserver::with_force_calibration`].

pub mod apply;
pub mod data;
pub mod fit;

pub use slidetrack_calibration::tactile_force::{AxisErrors, ForceModelKind, TactileForceCalibration};
