//! Why a calibration could not be done.

use std::path::PathBuf;

use thiserror::Error;

use crate::error::MarkerError;

/// Why a calibration could not be done.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum CalibrationError {
    /// The pattern description does not parse.
    #[error(
        "bad pattern {spec:?}: {reason} (examples: chessboard:9x6:0.025, charuco:5x7:0.04:0.02:DICT_6X6_250, circles-asym:4x11:0.02)"
    )]
    BadPattern {
        /// The description as given.
        spec: String,
        /// What is wrong with it.
        reason: String,
    },
    /// An image file could not be read or decoded.
    #[error("cannot read image {path} (missing, or neither JPEG nor PNG)")]
    UnreadableImage {
        /// The file.
        path: PathBuf,
    },
    /// The images do not all have the same size.
    #[error("{path} is {width}x{height} px but the first image is {expected_width}x{expected_height} px")]
    MixedSizes {
        /// The odd image.
        path: PathBuf,
        /// Its width (px).
        width: u32,
        /// Its height (px).
        height: u32,
        /// The first image's width (px).
        expected_width: u32,
        /// The first image's height (px).
        expected_height: u32,
    },
    /// Too few views show the pattern.
    #[error("{pattern} found in {found} of {total} image(s), {needed} needed{}", without_list(.without_pattern))]
    TooFewViews {
        /// The pattern looked for.
        pattern: String,
        /// Views in which it was found.
        found: usize,
        /// Views looked at.
        total: usize,
        /// Views needed.
        needed: usize,
        /// The images without the pattern (at most the first 10).
        without_pattern: Vec<String>,
    },
    /// The result is not a usable camera (non-finite or non-positive focal lengths).
    #[error("calibration diverged: fx = {fx}, fy = {fy}, RMS {rms_px} px")]
    Diverged {
        /// Focal length along x (px).
        fx: f64,
        /// Focal length along y (px).
        fy: f64,
        /// RMS reprojection error (px).
        rms_px: f64,
    },
    /// The ChArUco dictionary could not be made.
    #[error(transparent)]
    Marker(#[from] MarkerError),
    /// An OpenCV call failed.
    #[error("OpenCV {operation} failed: {source}")]
    OpenCv {
        /// The OpenCV function.
        operation: &'static str,
        /// OpenCV's error.
        #[source]
        source: opencv::Error,
    },
}

fn without_list(names: &[String]) -> String {
    if names.is_empty() { String::new() } else { format!("; no pattern in: {}", names.join(", ")) }
}
