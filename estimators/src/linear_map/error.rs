//! Why a map could not be fitted or read.

use thiserror::Error;

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
