//! The simulated RGB-D camera's error type.

use thiserror::Error;

/// Why a simulated RGB-D scene could not be built.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum RgbdSimError {
    /// The camera placement is unusable.
    #[error("camera placement: {0}")]
    Camera(#[from] crate::camera::SimCameraError),
    /// The intrinsics are not usable (sizes, focal lengths).
    #[error("RGB-D intrinsics are not usable: {width}x{height} px, fx = {fx} px, fy = {fy} px")]
    BadIntrinsics {
        /// Width (px).
        width: u32,
        /// Height (px).
        height: u32,
        /// Focal length x (px).
        fx: f64,
        /// Focal length y (px).
        fy: f64,
    },
    /// A number of the configuration is out of its range.
    #[error("{what} = {value} is out of range ({expected})")]
    OutOfRange {
        /// The setting.
        what: &'static str,
        /// The value given.
        value: f64,
        /// The valid range, in words.
        expected: &'static str,
    },
}
