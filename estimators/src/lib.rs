#![doc = include_str!("../README.md")]
#![warn(missing_docs)]

pub mod constant_velocity;
pub mod dekf;
pub mod derivative;
pub mod kf;
pub mod linear_map;
pub mod maskukf;
pub mod metrics;
pub mod orientation;
pub mod pose_smoother;
pub mod roft;
pub mod rts;
pub mod seq_kf;
pub mod seq_ukf;
pub mod slip;
pub mod ukf;

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
    /// The smoother could not invert the prior covariance of a step.
    #[error("the prior covariance of step {step} is singular")]
    SingularPrior {
        /// Index of the step whose prior could not be inverted.
        step: usize,
    },
    /// A sample time goes backwards or is not finite.
    #[error("sample {index} at {t_s} s is not after the previous sample")]
    TimeNotIncreasing {
        /// Index of the sample.
        index: usize,
        /// Its time (s).
        t_s: f64,
    },
    /// A covariance is not symmetric positive semi-definite (or holds NaN),
    /// so no matrix square root exists for the sigma points.
    #[error("the covariance is not positive semi-definite ({what})")]
    NotPositiveSemiDefinite {
        /// Which covariance.
        what: &'static str,
    },
    /// A step produced NaN or infinity; the state was left as it was.
    #[error("the {what} became non-finite; the step was discarded")]
    NonFiniteState {
        /// Which quantity.
        what: &'static str,
    },
    /// Sizes of the inputs do not agree.
    #[error("dimension mismatch in {what}: expected {expected}, got {got}")]
    DimensionMismatch {
        /// Which input.
        what: &'static str,
        /// The size expected.
        expected: usize,
        /// The size given.
        got: usize,
    },
}
