//! [`MarkerDetector`]: OpenCV's ArUco detection with corners refined to sub-pixel.

use opencv::aruco::{self, DetectorParametersTrait};
use opencv::core::{Mat, MatTraitConst, Point2f, Ptr, Rect, Size, TermCriteria, ToInputArray, Vec3b, Vector};
use opencv::imgproc;
use slidetrack_core::{Image, PixelFormat};

use super::detection::{MarkerDetection, PixelRoi};
use super::dictionary::Dictionary;
use crate::error::{MarkerError, OpenCvContext};

/// How detected corners are refined.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum CornerRefinement {
    /// The corners of OpenCV's polygon fit, on the contour pixels (integer
    /// positions, about half a pixel inside the marker's black border). This
    /// is OpenCV's default, and what its published test corners assert.
    None,
    /// `cornerSubPix` with a window of half-size `clamp(cell / 2, 2, 5)` px,
    /// so that the window stays within about one cell of the corner
    /// (OpenCV 4.6's fixed 5 px window pulls the corners of small markers,
    /// whose inner cells fall inside it, by up to a pixel).
    #[default]
    Subpixel,
}

/// Finds ArUco markers of one dictionary in images.
///
/// Parameters: OpenCV's defaults (adaptive thresholds with windows 3, 13,
/// 23 px), candidates kept apart down to a mean corner distance of 2.5 % of
/// the perimeter (OpenCV's 5 % merges a marker with the outline of a sticker
/// only one cell wider, and keeps the sticker), then [`CornerRefinement`]
/// (sub-pixel by default: 30 iterations or 0.01 px). Runs on whatever threads
/// OpenCV is allowed (`opencv::core::set_num_threads`). For following one
/// marker through a video, [`super::MarkerTracker`] is about 25 times faster.
pub struct MarkerDetector {
    dictionary: Dictionary,
    parameters: Ptr<aruco::DetectorParameters>,
    refinement: CornerRefinement,
    gray: Mat,
    corners: Vector<Vector<Point2f>>,
    ids: Vector<i32>,
    rejected: Vector<Vector<Point2f>>,
}

impl MarkerDetector {
    /// A detector for `dictionary` with sub-pixel corners.
    pub fn new(dictionary: Dictionary) -> Result<MarkerDetector, MarkerError> {
        MarkerDetector::with_refinement(dictionary, CornerRefinement::Subpixel)
    }

    /// A detector for `dictionary` with the given corner refinement.
    pub fn with_refinement(
        dictionary: Dictionary,
        refinement: CornerRefinement,
    ) -> Result<MarkerDetector, MarkerError> {
        let mut parameters = aruco::DetectorParameters::create().cv("DetectorParameters::create")?;
        // Refinement is done here, with a window sized per marker.
        parameters.set_corner_refinement_method(aruco::CornerRefineMethod::CORNER_REFINE_NONE as i32);
        parameters.set_min_marker_distance_rate(0.025);
        Ok(MarkerDetector {
            dictionary,
            parameters,
            refinement,
            gray: Mat::default(),
            corners: Vector::new(),
            ids: Vector::new(),
            rejected: Vector::new(),
        })
    }

    /// Tunes the detector for one marker of about `side_px` inside `roi`: one
    /// adaptive-threshold window of about two cells, and contours shorter
    /// than half the marker's perimeter dropped.
    pub(crate) fn tune_for_marker(&mut self, side_px: f64, roi: PixelRoi) {
        let cell_px = side_px / (self.dictionary.cells() as f64 + 2.0);
        let window_px = ((2.0 * cell_px).round() as i32 | 1).clamp(3, 99);
        self.parameters.set_adaptive_thresh_win_size_min(window_px);
        self.parameters.set_adaptive_thresh_win_size_max(window_px);
        let max_dim = f64::from(roi.width.max(roi.height).max(1));
        let min_rate = (0.5 * 4.0 * side_px / max_dim).clamp(0.01, 1.0);
        self.parameters.set_min_marker_perimeter_rate(min_rate);
    }

    /// The dictionary searched for.
    pub fn dictionary(&self) -> &Dictionary {
        &self.dictionary
    }

    /// Every marker of the dictionary in the whole image.
    pub fn detect(&mut self, image: &Image) -> Result<Vec<MarkerDetection>, MarkerError> {
        let full = PixelRoi { x: 0, y: 0, width: image.width, height: image.height };
        self.detect_in(image, full)
    }

    /// Every marker of the dictionary inside `roi` (clipped to the image);
    /// corners are in full-image pixels.
    pub fn detect_in(&mut self, image: &Image, roi: PixelRoi) -> Result<Vec<MarkerDetection>, MarkerError> {
        MarkerError::check_bytes(image)?;
        let x0 = roi.x.min(image.width);
        let y0 = roi.y.min(image.height);
        let width = roi.width.min(image.width - x0);
        let height = roi.height.min(image.height - y0);
        if width < 8 || height < 8 {
            return Ok(Vec::new());
        }
        let rect = Rect::new(x0 as i32, y0 as i32, width as i32, height as i32);
        let (rows, cols) = (image.height as i32, image.width as i32);
        let offset = [f64::from(x0), f64::from(y0)];
        match image.format {
            PixelFormat::Gray8 => {
                let mat = Mat::new_rows_cols_with_data::<u8>(rows, cols, &image.data).cv("Mat from image")?;
                let view = Mat::roi(&mat, rect).cv("Mat::roi")?;
                self.detect_gray(&view, offset)
            }
            PixelFormat::Rgb8 => {
                let mat =
                    Mat::new_rows_cols_with_bytes::<Vec3b>(rows, cols, &image.data).cv("Mat from image")?;
                let view = Mat::roi(&mat, rect).cv("Mat::roi")?;
                self.detect_converted(&view, imgproc::COLOR_RGB2GRAY, offset)
            }
        }
    }

    /// Every marker in an OpenCV image (8-bit gray, or BGR as `imread` gives).
    pub fn detect_mat(&mut self, image: &Mat) -> Result<Vec<MarkerDetection>, MarkerError> {
        if image.channels() == 1 {
            self.detect_gray(image, [0.0, 0.0])
        } else {
            self.detect_converted(image, imgproc::COLOR_BGR2GRAY, [0.0, 0.0])
        }
    }

    /// Converts to gray in the detector's buffer, then detects.
    fn detect_converted(
        &mut self,
        colour: &impl ToInputArray,
        code: i32,
        offset: [f64; 2],
    ) -> Result<Vec<MarkerDetection>, MarkerError> {
        let mut gray = std::mem::take(&mut self.gray);
        let result = imgproc::cvt_color(colour, &mut gray, code, 0)
            .cv("cvtColor")
            .and_then(|()| self.detect_gray(&gray, offset));
        self.gray = gray;
        result
    }

    /// Detects in a gray image; `offset` (px) is added to the corners.
    fn detect_gray(
        &mut self,
        gray: &impl ToInputArray,
        offset: [f64; 2],
    ) -> Result<Vec<MarkerDetection>, MarkerError> {
        aruco::detect_markers(
            gray,
            self.dictionary.opencv(),
            &mut self.corners,
            &mut self.ids,
            &self.parameters,
            &mut self.rejected,
        )
        .cv("detectMarkers")?;
        let cells_per_side = self.dictionary.cells() as f64 + 2.0;
        let criteria =
            TermCriteria::new(opencv::core::TermCriteria_COUNT + opencv::core::TermCriteria_EPS, 30, 0.01)
                .cv("TermCriteria")?;
        let mut found = Vec::with_capacity(self.ids.len());
        for (id, mut corners) in self.ids.iter().zip(self.corners.iter()) {
            let mut detection = MarkerDetection { id: id.max(0) as u32, corners_px: [[0.0; 2]; 4] };
            let read =
                |corners: &Vector<Point2f>, detection: &mut MarkerDetection| -> Result<(), MarkerError> {
                    for (k, c) in detection.corners_px.iter_mut().enumerate() {
                        let p = corners.get(k).cv("corner")?;
                        *c = [f64::from(p.x) + offset[0], f64::from(p.y) + offset[1]];
                    }
                    Ok(())
                };
            read(&corners, &mut detection)?;
            if self.refinement == CornerRefinement::Subpixel {
                let cell_px = detection.side_px() / cells_per_side;
                let half_window = ((cell_px / 2.0).floor() as i32).clamp(2, 5);
                let window = Size::new(half_window, half_window);
                imgproc::corner_sub_pix(gray, &mut corners, window, Size::new(-1, -1), criteria)
                    .cv("cornerSubPix")?;
                read(&corners, &mut detection)?;
            }
            found.push(detection);
        }
        Ok(found)
    }
}
