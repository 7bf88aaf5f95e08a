#![doc = include_str!("../README.md")]
#![warn(missing_docs)]

pub mod kf;

use thiserror::Error;

/// Failures of the filters: numerical conditions the caller must handle.
#[derive(Clone, Debug, Error, PartialEq)]
#[non_exhaustive]
pub enum EstimatorError {
    /// The innovation covariance `S` could not be inverted.
    #[error("the innovation covariance is singular")]
    SingularInnovation,
    /// A measurement holds NaN or infinity.
    #[error("the measurement is not finite")]
    NonFiniteMeasurement,
}
