//! Detection in a region of interest around the previous detection.
//!
//! Why (measured with `cargo bench -p slidetrack-calibration --bench
//! camera_frame`, release build, OpenCV on one thread, 2-core Xeon under load):
//! detecting the marker in a whole 640x480 simulated frame takes 4.2 to 4.9 ms
//! (median), more than the 3 ms the simulator may spend on a whole camera
//! frame (render, JPEG, detection, pose). Searching the previous marker's
//! bounding box grown by 35 % of its side (about 155 x 155 px for a 90 px
//! marker), with one adaptive-threshold window sized from the marker's cells
//! instead of OpenCV's three and contours shorter than half the marker's
//! perimeter ignored, takes 0.19 to 0.20 ms with the same sub-pixel corners.
//! The whole frame is searched again only when the marker is lost.

use slidetrack_core::Image;

use super::detection::{MarkerDetection, PixelRoi};
use super::detector::MarkerDetector;
use super::dictionary::Dictionary;
use crate::error::MarkerError;

/// Margin of the region of interest around the previous marker, as a
/// fraction of its side (the white sticker adds 1/8 of the side for a 6x6
/// marker; the rest is motion room).
const MARGIN_OF_SIDE: f64 = 0.35;

/// Smallest margin (px).
const MIN_MARGIN_PX: f64 = 12.0;

/// Follows one marker from frame to frame, searching a region of interest
/// around its previous detection and the whole frame only when it is lost.
pub struct MarkerTracker {
    search: MarkerDetector,
    roi: MarkerDetector,
    target_id: u32,
    last: Option<MarkerDetection>,
    full_frame_searches: u64,
    roi_hits: u64,
}

impl MarkerTracker {
    /// A tracker for marker `target_id` of `dictionary`.
    pub fn new(dictionary: Dictionary, target_id: u32) -> Result<MarkerTracker, MarkerError> {
        let roi = MarkerDetector::new(Dictionary::from_name(dictionary.name())?)?;
        let search = MarkerDetector::new(dictionary)?;
        Ok(MarkerTracker { search, roi, target_id, last: None, full_frame_searches: 0, roi_hits: 0 })
    }

    /// The marker in `image`, if found: first in the region of interest
    /// around the previous detection, then, if it is not there, in the whole
    /// frame.
    pub fn detect(&mut self, image: &Image) -> Result<Option<MarkerDetection>, MarkerError> {
        if let Some(previous) = &self.last {
            let roi = roi_around(previous, image);
            self.roi.tune_for_marker(previous.side_px(), roi);
            let found = self.roi.detect_in(image, roi)?.into_iter().find(|d| d.id == self.target_id);
            if let Some(found) = found {
                self.roi_hits += 1;
                self.last = Some(found.clone());
                return Ok(Some(found));
            }
        }
        self.full_frame_searches += 1;
        let found = self.search.detect(image)?.into_iter().find(|d| d.id == self.target_id);
        self.last = found.clone();
        Ok(found)
    }

    /// Frames found in the region of interest, and full-frame searches so far.
    pub fn counts(&self) -> (u64, u64) {
        (self.roi_hits, self.full_frame_searches)
    }

    /// The marker id followed.
    pub fn target_id(&self) -> u32 {
        self.target_id
    }

    /// Forgets the previous detection: the next frame is searched whole.
    pub fn reset(&mut self) {
        self.last = None;
    }
}

/// The region of interest: the previous corners' bounding box plus a margin.
fn roi_around(previous: &MarkerDetection, image: &Image) -> PixelRoi {
    let margin = (previous.side_px() * MARGIN_OF_SIDE).max(MIN_MARGIN_PX);
    let (mut u0, mut v0, mut u1, mut v1) = (f64::MAX, f64::MAX, f64::MIN, f64::MIN);
    for &[u, v] in &previous.corners_px {
        u0 = u0.min(u);
        v0 = v0.min(v);
        u1 = u1.max(u);
        v1 = v1.max(v);
    }
    let clamp = |v: f64, max: u32| v.clamp(0.0, f64::from(max)) as u32;
    let (x0, y0) = (clamp(u0 - margin, image.width), clamp(v0 - margin, image.height));
    let (x1, y1) = (clamp(u1 + margin + 1.0, image.width), clamp(v1 + margin + 1.0, image.height));
    PixelRoi { x: x0, y: y0, width: x1 - x0, height: y1 - y0 }
}
