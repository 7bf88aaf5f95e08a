//! [`VisionError`]: everything the vision front-ends and trackers can refuse.

use std::path::PathBuf;

use slidetrack_estimators::EstimatorError;
use slidetrack_estimators::maskukf::{MaskUkfError, ModelError};
use slidetrack_estimators::roft::RoftError;
use slidetrack_session::SessionError;
use thiserror::Error;

mod external;

pub use external::ExternalError;

/// Errors of the vision crate.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum VisionError {
    /// An OpenCV call failed.
    #[error("OpenCV {context}: {message}")]
    OpenCv {
        /// What was being done.
        context: &'static str,
        /// OpenCV's message.
        message: String,
    },
    /// A file could not be read.
    #[error("cannot read {path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// A file was read but its content is not usable.
    #[error("{path}: {detail}")]
    BadFile {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        detail: String,
    },
    /// The model file's extension is not one we read.
    #[error("{path}: unsupported object model format (use .obj, .ply or .xyz)")]
    UnsupportedModel {
        /// The file.
        path: PathBuf,
    },
    /// The object model is unusable.
    #[error("object model: {0}")]
    Model(#[from] ModelError),
    /// Two images that must match in size do not.
    #[error("{what}: {width}x{height} px, expected {expected_width}x{expected_height} px")]
    SizeMismatch {
        /// Which image.
        what: &'static str,
        /// Its width (px).
        width: u32,
        /// Its height (px).
        height: u32,
        /// Expected width (px).
        expected_width: u32,
        /// Expected height (px).
        expected_height: u32,
    },
    /// An image does not have the layout asked for.
    #[error("{what}: {detail}")]
    BadImage {
        /// Which image.
        what: &'static str,
        /// What is wrong.
        detail: String,
    },
    /// A number or setting given to the crate is not usable.
    #[error("{what}: {detail}")]
    BadValue {
        /// Which value.
        what: &'static str,
        /// What is wrong.
        detail: String,
    },
    /// Reading or writing a session failed.
    #[error(transparent)]
    Session(#[from] SessionError),
    /// A depth frame could not be stored or read back.
    #[error(transparent)]
    Depth(#[from] slidetrack_session::DepthCodecError),
    /// A session lacks what a reader needs.
    #[error("{path}: {detail}")]
    BadSession {
        /// The session file.
        path: PathBuf,
        /// What is missing.
        detail: String,
    },
    /// MaskUKF refused a step.
    #[error("MaskUKF: {0}")]
    MaskUkf(#[from] MaskUkfError),
    /// ROFT refused a step.
    #[error("ROFT: {0}")]
    Roft(#[from] RoftError),
    /// A filter refused its inputs.
    #[error("filter: {0}")]
    Estimator(#[from] EstimatorError),
    /// Marker detection or its pose failed.
    #[error("ArUco: {0}")]
    Marker(#[from] slidetrack_calibration::MarkerError),
    /// The external measurement source refused a message or its socket failed.
    #[error("external source: {0}")]
    External(#[from] ExternalError),
    /// A device failed.
    #[error(transparent)]
    Device(#[from] slidetrack_core::DeviceError),
}

/// Maps OpenCV results onto [`VisionError::OpenCv`] with a context.
pub(crate) trait OpenCvContext<T> {
    fn cv(self, context: &'static str) -> Result<T, VisionError>;
}

impl VisionError {
    /// `Ok` when an image of `size` (width, height in px) has the `expected`
    /// size; otherwise [`VisionError::SizeMismatch`] naming `what`.
    pub fn check_size(what: &'static str, size: (u32, u32), expected: (u32, u32)) -> Result<(), VisionError> {
        if size == expected {
            return Ok(());
        }
        Err(VisionError::SizeMismatch {
            what,
            width: size.0,
            height: size.1,
            expected_width: expected.0,
            expected_height: expected.1,
        })
    }
}

impl<T> OpenCvContext<T> for opencv::Result<T> {
    fn cv(self, context: &'static str) -> Result<T, VisionError> {
        self.map_err(|e| VisionError::OpenCv { context, message: e.message })
    }
}
