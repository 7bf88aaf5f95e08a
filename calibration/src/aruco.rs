//! ArUco dictionaries and marker detection (OpenCV 4.6 `aruco` contrib module).

mod detection;
mod detector;
mod dictionary;
mod tracker;

pub use detection::{MarkerDetection, PixelRoi};
pub use detector::{CornerRefinement, MarkerDetector};
pub use dictionary::{Dictionary, marker_pattern};
pub use tracker::MarkerTracker;

#[cfg(test)]
mod tests;
