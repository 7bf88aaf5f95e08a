//! ROFT (thesis Chapter 5): real-time optical-flow-aided 6D object pose and
//! velocity tracking, a cascade of three stages run once per RGB-D frame:
//!
//! 1. [`mask::MaskSync`]: the delayed, low-rate masks `M^d` are synchronised
//!    with the frames through the optical flow (5.1)-(5.3);
//! 2. [`velocity::VelocityTracker`]: the spatial velocity `𝒱` from the flow of
//!    the mask's pixels, with a sequential linear Kalman filter (5.4)-(5.9);
//! 3. the pose UKF with a unit quaternion ([`pose`], (5.10)-(5.18)) fuses the
//!    velocities with the delayed, low-rate pose measurements `T^d`: a pose
//!    for an earlier frame `k` rewinds the filter to frame `k`, fuses it there
//!    with `𝒱_k`, and replays the buffered velocities up to the current frame
//!    (Sec. 5.4.5); before fusing, the pose is checked against the measured
//!    depth by rendering the object at both hypotheses (5.19)-(5.20).
//!
//! The optical flow and the depth rendering come from the caller (the
//! `vision` crate computes the flow with OpenCV and renders the object mesh);
//! this module is pure math. Defaults are Table 5.1. Switches in
//! [`RoftConfig`] disable each component for the ablations of Table 5.6.

pub mod image;
pub mod mask;
pub mod pose;
mod tracker;
pub mod velocity;

#[cfg(test)]
mod tests;

pub use image::{DepthMap, FlowField, Mask, Pinhole, PixelBox, SharedFlow};
pub use mask::{DelayedMaskUse, MaskSync, propagate};
pub use tracker::{PoseUse, Roft, RoftInput, RoftReport};
pub use velocity::{VelocityConfig, VelocityTracker, flow_jacobian};

use nalgebra::Isometry3;
use thiserror::Error;

use crate::ukf::UtParams;

/// Renders the depth of the object model, for the outlier test (5.19).
///
/// # Contract
/// `render` writes, for each of `pixels`, the depth (m) of the object placed
/// at `camera_from_object` as seen through that pixel, or `0` where the
/// object is not seen. It must not block on I/O.
pub trait DepthRenderer: Send {
    /// Fills `depth_m` (cleared first) with one value per pixel.
    fn render(&mut self, camera_from_object: &Isometry3<f64>, pixels: &[(u32, u32)], depth_m: &mut Vec<f32>);
}

/// Parameters of ROFT: Table 5.1 and the switches of the ablations (Table 5.6).
#[derive(Clone, Debug, PartialEq)]
pub struct RoftConfig {
    /// `P_0` diagonal for `p` (m²), `v^m` ((m/s)²), `q` (rad²), `ω` ((rad/s)²).
    pub p0: [f64; 4],
    /// Power spectral density `Q_p` of the linear acceleration, (m/s)²/s.
    pub q_p: [f64; 3],
    /// `Q_ω` per step, (rad/s)².
    pub q_omega: [f64; 3],
    /// Measurement variances `R_p` (m²), `R_q` (rad²), `R_v` ((m/s)²), `R_ω` ((rad/s)²).
    pub r: [f64; 4],
    /// `γ` of the outlier test (5.20).
    pub gamma: f64,
    /// The velocity tracker (Table 5.1, lower half).
    pub velocity: VelocityConfig,
    /// Use the velocities in the pose UKF (off: "w/o velocity").
    pub use_velocity: bool,
    /// Use the pose measurements after the first (off: "w/o pose").
    pub use_pose: bool,
    /// Fuse delayed poses at their own frame and replay (off: "w/o pose sync.").
    pub pose_sync: bool,
    /// Reject poses with the depth-rendering test (off: "w/o outlier rej.").
    pub outlier_rejection: bool,
    /// Propagate masks with the flow (off: "w/o segm. sync.").
    pub mask_sync: bool,
    /// Frames of history kept for the synchronisation (flows, velocities,
    /// beliefs); delayed measurements older than this are dropped.
    pub history_frames: usize,
    /// At most this many mask pixels enter the depth comparison (5.19).
    pub max_outlier_pixels: usize,
    /// Unscented transform parameters.
    pub ut: UtParams,
}

impl Default for RoftConfig {
    fn default() -> RoftConfig {
        RoftConfig {
            p0: [1e-3; 4],
            q_p: [1.0; 3],
            q_omega: [1.0; 3],
            r: [1e-3, 1e-4, 1e-1, 1e-4],
            gamma: 2.0,
            velocity: VelocityConfig::default(),
            use_velocity: true,
            use_pose: true,
            pose_sync: true,
            outlier_rejection: true,
            mask_sync: true,
            history_frames: 30,
            max_outlier_pixels: 2000,
            ut: UtParams::default(),
        }
    }
}

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
