//! Why a ROFT step was refused.

use thiserror::Error;

use super::image::Pinhole;

/// Errors of a ROFT step; the tracker's state is unchanged.
#[derive(Clone, Debug, Error, PartialEq)]
#[non_exhaustive]
pub enum RoftError {
    /// A frame is not later than the previous one.
    #[error("frame at {t_ns} ns does not come after the previous frame at {previous_ns} ns")]
    OutOfOrder {
        /// The previous frame's time (ns).
        previous_ns: u64,
        /// This frame's time (ns).
        t_ns: u64,
    },
    /// The depth map does not have the camera's size.
    #[error("depth map is {width}x{height} px, the camera is {expected_width}x{expected_height} px")]
    DepthSize {
        /// Depth width (px).
        width: u32,
        /// Depth height (px).
        height: u32,
        /// Camera width (px).
        expected_width: u32,
        /// Camera height (px).
        expected_height: u32,
    },
    /// The intrinsics are unusable.
    #[error("camera intrinsics are not positive and finite: {0:?}")]
    BadIntrinsics(Pinhole),
    /// The initial pose is not finite.
    #[error("the initial pose is not finite")]
    BadInitialPose,
}
