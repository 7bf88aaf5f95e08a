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
//! checks the result against rendering every pixel).
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

use slidetrack_core::{BadMarkerPattern, JpegError, PlacementError};
use thiserror::Error;

mod blocks;
mod board;
mod board_face;
mod config;
mod face;
mod object;
mod raster;
mod render;
mod texture;

#[cfg(test)]
mod tests;

pub use board::Chessboard;
pub use board_face::BoardPrint;
pub use config::{BackgroundConfig, SimCameraConfig};
pub use object::ObjectAppearance;
pub use render::SimCameraRenderer;

/// Why a simulated camera could not be built or could not encode a frame.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum SimCameraError {
    /// The image size is zero or too large for JPEG (65535 px per side).
    #[error("image size {width}x{height} px is not usable (1..=65535 px per side)")]
    BadImageSize {
        /// Width (px).
        width: u32,
        /// Height (px).
        height: u32,
    },
    /// A focal length is not a positive finite number.
    #[error("focal lengths fx = {fx} px, fy = {fy} px must be positive")]
    BadFocalLength {
        /// Focal length along x (px).
        fx: f64,
        /// Focal length along y (px).
        fy: f64,
    },
    /// A configuration number is outside its valid range.
    #[error("{what} = {value} is out of range ({expected})")]
    OutOfRange {
        /// Name of the setting, as in the configuration file.
        what: &'static str,
        /// The value given.
        value: f64,
        /// The valid range, in words.
        expected: &'static str,
    },
    /// The camera placement gives no pose.
    #[error(transparent)]
    Placement(#[from] PlacementError),
    /// The background plane normal has zero length.
    #[error("background plane normal {normal_in_hand:?} has zero length")]
    BadBackgroundNormal {
        /// The normal as given, in the hand frame.
        normal_in_hand: [f64; 3],
    },
    /// The marker pattern's bit count does not match its size.
    #[error(transparent)]
    Marker(#[from] BadMarkerPattern),
    /// The board layout cannot be printed.
    #[error(transparent)]
    Board(#[from] slidetrack_core::BadBoardLayout),
    /// A board's markers do not match its layout (one pattern per marker, all of one size).
    #[error("the board has {expected} markers but {given} marker patterns of one size were given")]
    BoardMarkers {
        /// Markers of the layout.
        expected: usize,
        /// Patterns given.
        given: usize,
    },
    /// The JPEG encoder refused the image.
    #[error(transparent)]
    Jpeg(#[from] JpegError),
}
