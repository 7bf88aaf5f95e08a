//! The simulated RGB-D camera: colour, depth (with noise and invalid pixels)
//! and ground-truth masks of textured convex objects, for the vision trackers.
//!
//! Meshes and their rasterizer come from `slidetrack-render`, the frame types
//! from `slidetrack-core`.
//! - [`RgbdScene`]: one textured object in front of a static textured wall,
//!   rendered with Lambert shading, colour noise, depth noise growing with
//!   the square of the distance, depth dropouts at random, at grazing angles
//!   and at depth edges, and depth quantised to millimetres.
//! - [`FastMotion`]: smooth, fast 6D trajectories like Fast-YCB's (up to about
//!   60 cm/s and 270 deg/s) with their exact pose and velocity;
//!   [`FastSequence`] renders them at 30 Hz.
//! - [`InHandRgbd`]: the same rendering of the in-hand sliding scene, so that
//!   the vision trackers can run beside the dEKF.
//!
//! Frames, all right-handed: `camera` is OpenCV's optical frame (x right, y
//! down, z forward); `object` is the object's own frame, centred in its
//! bounding box. Deterministic: the same seed gives the same frames.

mod decal;
mod inhand;
mod motion;
mod scene;
mod texture;

#[cfg(test)]
mod tests;

pub use decal::MarkerDecal;
pub use inhand::InHandRgbd;
pub use motion::{FastMotion, FastMotionConfig, FastSequence, FastSequenceConfig, SimObjectKind};
pub use scene::{DepthNoise, RenderedRgbd, RgbdScene, RgbdSceneConfig};
pub use texture::Texture;

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
