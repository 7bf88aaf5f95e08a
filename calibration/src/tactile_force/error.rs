//! What can go wrong while fitting, reading or applying a tactile force calibration.

use std::path::PathBuf;

use thiserror::Error;

/// An error of the tactile force calibration.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum TactileForceError {
    /// Counts and reference forces of a taxel differ in number.
    #[error("taxel {taxel}: {counts} scans of counts but {forces} reference forces")]
    LengthMismatch {
        /// Taxel index (layout order).
        taxel: usize,
        /// Scans of counts.
        counts: usize,
        /// Reference forces.
        forces: usize,
    },
    /// Too few scans to fit the model's terms.
    #[error(
        "taxel {taxel}: {samples} scans are too few to fit {terms} terms per axis (need at least {needed})"
    )]
    TooFewSamples {
        /// Taxel index (layout order).
        taxel: usize,
        /// Scans given.
        samples: usize,
        /// Terms per axis of the model.
        terms: usize,
        /// Scans needed.
        needed: usize,
    },
    /// The counts do not vary enough to determine every term (no contact, or one direction only).
    #[error(
        "taxel {taxel}: the counts determine only {rank} of the {terms} terms per axis \
         (was the taxel ever pressed, in more than one direction?)"
    )]
    Degenerate {
        /// Taxel index (layout order).
        taxel: usize,
        /// Numerical rank of the design matrix.
        rank: usize,
        /// Terms per axis of the model.
        terms: usize,
    },
    /// The reference force on the taxel is zero throughout: nothing to fit.
    #[error("taxel {taxel}: its reference force is zero in every scan (was it ever pressed?)")]
    NoForce {
        /// Taxel index (layout order).
        taxel: usize,
    },
    /// A value is not a finite number.
    #[error("taxel {taxel}: {what} is not finite")]
    NotFinite {
        /// Taxel index (layout order).
        taxel: usize,
        /// Which value.
        what: &'static str,
    },
    /// The calibration file cannot be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// The calibration file is not valid TOML of this format.
    #[error("{path}: {detail}")]
    Parse {
        /// The file.
        path: PathBuf,
        /// What is wrong (line and field).
        detail: String,
    },
    /// The file is another format or version.
    #[error(
        "{path}: format {format:?} version {version}; expected {expected_format:?} version {expected_version}"
    )]
    Version {
        /// The file.
        path: PathBuf,
        /// The format it names.
        format: String,
        /// Its version.
        version: u32,
        /// The format this build reads.
        expected_format: &'static str,
        /// The version this build reads.
        expected_version: u32,
    },
    /// A taxel's map does not match the file's model.
    #[error("sensor {sensor:?} taxel {taxel}: {detail}")]
    BadTaxel {
        /// Sensor name.
        sensor: String,
        /// Taxel index within the sensor.
        taxel: usize,
        /// What is wrong.
        detail: String,
    },
    /// The calibration does not describe the tactile sensors it is applied to.
    #[error("the calibration does not fit the tactile layout: {detail}")]
    Layout {
        /// Which sensor differs and how.
        detail: String,
    },
}
