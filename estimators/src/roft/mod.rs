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

mod config;
mod error;
pub mod image;
pub mod mask;
pub mod pose;
mod tracker;
pub mod velocity;

#[cfg(test)]
mod tests;

pub use config::{DepthRenderer, RoftConfig};
pub use error::RoftError;
pub use image::{DepthMap, FlowField, Mask, Pinhole, PixelBox, SharedFlow};
pub use mask::{DelayedMaskUse, MaskSync, propagate};
pub use tracker::{PoseUse, Roft, RoftInput, RoftReport};
pub use velocity::{VelocityConfig, VelocityTracker, flow_jacobian};
