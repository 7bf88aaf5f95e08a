//! The simulated RGB-D camera: colour, depth (with noise and invalid pixels)
//! and ground-truth masks of textured convex objects, for the vision trackers.
//!
//! Meshes and their rasterizer come from `slidetrack-render`, the frame types
//! from `slidetrack-core`.
//! - [`RgbdScene`]: one textured object in front of a static textured wall,
//!   rendered with Lambert shading, colour noise, and the depth of a
//!   triangulating sensor ([`DepthNoise`]): an error growing with the square
//!   of the distance and correlated between neighbouring pixels, disparity
//!   steps, dropouts at random, at grazing angles and at depth edges, in
//!   whole millimetres.
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
mod depth_noise;
mod error;
mod inhand;
mod motion;
mod scene;
mod texture;

#[cfg(test)]
mod tests;

pub use decal::MarkerDecal;
pub use depth_noise::DepthNoise;
pub use error::RgbdSimError;
pub use inhand::InHandRgbd;
pub use motion::{FastMotion, FastMotionConfig, FastSequence, FastSequenceConfig, SimObjectKind};
pub use scene::{RenderedRgbd, RgbdScene, RgbdSceneConfig};
pub use texture::Texture;
