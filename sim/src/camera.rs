//! The simulated camera: renders the ArUco marker on the object.
//!
//! A pinhole camera with plumb-bob distortion looks at the object held in the
//! hand. Every output pixel is lit by the rays through its (distorted) pixel
//! footprint: the rays at the pixel corners are undistorted once at start-up
//! ([`CameraIntrinsics::undistort_pixel`](slidetrack_core::CameraIntrinsics::undistort_pixel)),
//! then intersected with the plane of the object's marker face (per frame)
//! and with a static textured background plane behind the object (once).
//! Pixels that straddle a colour edge (marker cells, sticker, face outline)
//! average 8 samples on an n-rooks pattern; the image is then blurred
//! (Gaussian), Gaussian noise is added and the result quantised to 8 bits.
//!
//! Per frame only the neighbourhood of the object's colour edges is rendered
//! pixel by pixel and blurred: its bounding box is cut into 4 px blocks, a
//! block whose corners show one colour is filled with it, and the blurred
//! background computed at start-up is left as it is (see `blocks.rs`; a test
//! checks the result against rendering every pixel). Where the process may
//! run on two cores the lower half of the block rows is drawn on a second
//! thread, with the same result to the byte.
//!
//! Frames, all right-handed:
//! - `hand`: origin at the palm, x forward towards the object, y left, z up.
//! - `object`: the object's own frame; its marker face looks along +x, the
//!   face's "up" is +z and, seen from the camera, its "right" is +y.
//! - `camera`: OpenCV convention, x right, y down, z forward (optical axis).
//! - `marker`: OpenCV's ArUco convention, origin at the marker centre, x right,
//!   y up (as printed), z out of the face towards the viewer.
//!
//! The module does not depend on OpenCV: the marker's bits come from the
//! caller as a [`MarkerPattern`] (the calibration crate extracts them from
//! OpenCV's dictionaries).

mod blocks;
mod board;
mod board_face;
mod config;
mod error;
mod face;
mod object;
mod raster;
mod render;
mod texture;

#[cfg(test)]
mod golden_tests;
#[cfg(test)]
mod tests;

pub use board::Chessboard;
pub use board_face::BoardPrint;
pub use config::{BackgroundConfig, SimCameraConfig};
pub use error::SimCameraError;
pub use object::ObjectAppearance;
pub use render::SimCameraRenderer;
