//! [`GraspError`]: why the detector's settings or the metrics' inputs are refused.

use thiserror::Error;

/// Failures of the grasp detector's settings and of its metrics' inputs.
#[derive(Clone, Debug, Error, PartialEq)]
#[non_exhaustive]
pub enum GraspError {
    /// A setting of [`GraspDetectorConfig`] is out of range.
    #[error("grasp detector setting {field} = {value} {reason}")]
    InvalidConfig {
        /// Name of the setting.
        field: &'static str,
        /// Its value (unit of the setting).
        value: f64,
        /// The range it must lie in.
        reason: &'static str,
    },
    /// Two inputs that pair up element by element have different lengths.
    #[error("{what}: {left} against {right} entries")]
    LengthMismatch {
        /// Which inputs.
        what: &'static str,
        /// Length of the first.
        left: usize,
        /// Length of the second.
        right: usize,
    },
    /// A score is NaN, so it cannot be ranked.
    #[error("score {index} is NaN")]
    NanScore {
        /// Its index.
        index: usize,
    },
}
