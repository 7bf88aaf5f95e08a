//! The simulated camera's error type.

use slidetrack_core::{BadMarkerPattern, JpegError, PlacementError};
use thiserror::Error;

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
