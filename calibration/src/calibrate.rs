//! Intrinsics calibration from views of a planar pattern, on OpenCV:
//! chessboards (`findChessboardCorners` + `cornerSubPix`), ChArUco boards
//! (ArUco markers, then `interpolateCornersCharuco`) and asymmetric circle
//! grids (`findCirclesGrid`), then `calibrateCamera` with plumb-bob
//! distortion.

use std::fmt;
use std::path::Path;
use std::str::FromStr;

use opencv::aruco::{self, CharucoBoardTraitConst};
use opencv::core::{self, Mat, MatTraitConst, Point2f, Point3f, Ptr, Size, TermCriteria, Vector};
use opencv::prelude::*;
use opencv::{calib3d, imgproc};
use slidetrack_core::{CameraIntrinsics, Image, PixelFormat};

use crate::aruco::Dictionary;
use crate::error::MarkerError;

#[path = "calibrate_error.rs"]
mod error;
#[path = "calibrate_pattern.rs"]
mod pattern;

pub use error::CalibrationError;
pub use pattern::Pattern;

pub(crate) trait Cv<T> {
    fn cv(self, operation: &'static str) -> Result<T, CalibrationError>;
}

impl<T> Cv<T> for opencv::Result<T> {
    fn cv(self, operation: &'static str) -> Result<T, CalibrationError> {
        self.map_err(|source| CalibrationError::OpenCv { operation, source })
    }
}

/// The pattern seen in one image: image points (px) and the matching points
/// on the pattern (m, pattern frame, z = 0).
#[derive(Clone, Debug, PartialEq)]
pub struct PatternView {
    /// Detected points (px), OpenCV convention (integer = pixel centre).
    pub image_points: Vec<[f32; 2]>,
    /// The same points on the pattern (m).
    pub object_points: Vec<[f32; 3]>,
}

/// Finds a [`Pattern`] in gray images.
pub struct PatternFinder {
    pattern: Pattern,
    charuco: Option<(Ptr<aruco::CharucoBoard>, Dictionary, Ptr<aruco::DetectorParameters>)>,
}

impl fmt::Debug for PatternFinder {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("PatternFinder").field("pattern", &self.pattern).finish()
    }
}

impl PatternFinder {
    /// A finder for `pattern`.
    pub fn new(pattern: Pattern) -> Result<PatternFinder, CalibrationError> {
        let charuco = match &pattern {
            Pattern::Charuco { squares, square_m, marker_m, dictionary } => {
                let dict = Dictionary::from_name(dictionary)?;
                let board = aruco::CharucoBoard::create(
                    squares[0] as i32,
                    squares[1] as i32,
                    *square_m as f32,
                    *marker_m as f32,
                    dict.opencv(),
                )
                .cv("CharucoBoard::create")?;
                let params = aruco::DetectorParameters::create().cv("DetectorParameters::create")?;
                Some((board, dict, params))
            }
            _ => None,
        };
        Ok(PatternFinder { pattern, charuco })
    }

    /// The pattern looked for.
    pub fn pattern(&self) -> &Pattern {
        &self.pattern
    }

    /// The pattern in an 8-bit gray image, or `None` when it is not (fully) there.
    pub fn find(&mut self, gray: &Mat) -> Result<Option<PatternView>, CalibrationError> {
        match self.pattern.clone() {
            Pattern::Chessboard { inner_corners, square_m } => find_chessboard(gray, inner_corners, square_m),
            Pattern::CirclesAsym { grid, spacing_m } => find_circles(gray, grid, spacing_m),
            Pattern::Charuco { .. } => self.find_charuco(gray),
        }
    }

    /// The pattern in an image from a camera (gray or RGB).
    pub fn find_in_image(&mut self, image: &Image) -> Result<Option<PatternView>, CalibrationError> {
        let gray = gray_mat(image)?;
        self.find(&gray)
    }

    fn find_charuco(&mut self, gray: &Mat) -> Result<Option<PatternView>, CalibrationError> {
        let Some((board, dict, params)) = &self.charuco else { return Ok(None) };
        let mut corners = Vector::<Vector<Point2f>>::new();
        let mut ids = Vector::<i32>::new();
        let mut rejected = Vector::<Vector<Point2f>>::new();
        aruco::detect_markers(gray, dict.opencv(), &mut corners, &mut ids, params, &mut rejected)
            .cv("detectMarkers")?;
        if ids.len() < 2 {
            return Ok(None);
        }
        let mut charuco_corners = Vector::<Point2f>::new();
        let mut charuco_ids = Vector::<i32>::new();
        let no_camera = Mat::default();
        aruco::interpolate_corners_charuco(
            &corners,
            &ids,
            gray,
            board,
            &mut charuco_corners,
            &mut charuco_ids,
            &no_camera,
            &no_camera,
            2,
        )
        .cv("interpolateCornersCharuco")?;
        let board_corners = board.chessboard_corners();
        let mut view = PatternView { image_points: Vec::new(), object_points: Vec::new() };
        for (id, p) in charuco_ids.iter().zip(charuco_corners.iter()) {
            let Some(q) = usize::try_from(id).ok().and_then(|i| board_corners.get(i).ok()) else { continue };
            view.image_points.push([p.x, p.y]);
            view.object_points.push([q.x, q.y, q.z]);
        }
        // Fewer corners do not constrain a homography well.
        Ok((view.image_points.len() >= 6).then_some(view))
    }
}

/// Chessboard corners as OpenCV's calibration sample finds them: adaptive
/// threshold, normalised image, fast check, then `cornerSubPix` with a
/// window of half-size 11 px (smaller when the squares are under 16 px), 30
/// iterations or 1e-4 px.
fn find_chessboard(
    gray: &Mat,
    inner: [u32; 2],
    square_m: f64,
) -> Result<Option<PatternView>, CalibrationError> {
    let size = Size::new(inner[0] as i32, inner[1] as i32);
    let mut corners = Vector::<Point2f>::new();
    let flags =
        calib3d::CALIB_CB_ADAPTIVE_THRESH | calib3d::CALIB_CB_NORMALIZE_IMAGE | calib3d::CALIB_CB_FAST_CHECK;
    if !calib3d::find_chessboard_corners(gray, size, &mut corners, flags).cv("findChessboardCorners")? {
        return Ok(None);
    }
    // OpenCV's sample window (half-size 11 px); on boards whose squares are
    // under 16 px it would reach the neighbouring corners, so it shrinks.
    let spacing = min_neighbour_distance(&corners, inner[0] as usize);
    let half = if spacing >= 16.0 { 11 } else { ((spacing / 2.0).floor() as i32 - 1).max(2) };
    let criteria =
        TermCriteria::new(core::TermCriteria_EPS + core::TermCriteria_COUNT, 30, 1e-4).cv("TermCriteria")?;
    imgproc::corner_sub_pix(gray, &mut corners, Size::new(half, half), Size::new(-1, -1), criteria)
        .cv("cornerSubPix")?;
    let object_points = (0..inner[1])
        .flat_map(|j| {
            (0..inner[0])
                .map(move |i| [(f64::from(i) * square_m) as f32, (f64::from(j) * square_m) as f32, 0.0])
        })
        .collect();
    Ok(Some(PatternView { image_points: corners.iter().map(|p| [p.x, p.y]).collect(), object_points }))
}

/// Smallest distance between neighbouring corners along the rows (px).
fn min_neighbour_distance(corners: &Vector<Point2f>, per_row: usize) -> f64 {
    let pts: Vec<Point2f> = corners.iter().collect();
    pts.chunks(per_row.max(1))
        .flat_map(|row| row.windows(2).map(|w| f64::from((w[1].x - w[0].x).hypot(w[1].y - w[0].y))))
        .fold(f64::INFINITY, f64::min)
}

/// Circle centres of an asymmetric grid: `grid = [circles per row, rows]`,
/// centre `(i, j)` (row `j`) at `((2 i + j mod 2) s, j s)` as in OpenCV's sample.
fn find_circles(gray: &Mat, grid: [u32; 2], spacing_m: f64) -> Result<Option<PatternView>, CalibrationError> {
    let size = Size::new(grid[0] as i32, grid[1] as i32);
    let mut centres = Vector::<Point2f>::new();
    // OpenCV 4.6's binding cannot pass its default detector through a null
    // pointer, so the (default) blob detector is created here.
    let params = opencv::features2d::SimpleBlobDetector_Params::default().cv("SimpleBlobDetector")?;
    let blobs: opencv::core::Ptr<opencv::features2d::Feature2D> =
        opencv::features2d::SimpleBlobDetector::create(params).cv("SimpleBlobDetector")?.into();
    let found =
        calib3d::find_circles_grid(gray, size, &mut centres, calib3d::CALIB_CB_ASYMMETRIC_GRID, Some(&blobs))
            .cv("findCirclesGrid")?;
    if !found {
        return Ok(None);
    }
    let object_points = (0..grid[1])
        .flat_map(|j| {
            (0..grid[0]).map(move |i| {
                let x = f64::from(2 * i + j % 2) * spacing_m;
                [x as f32, (f64::from(j) * spacing_m) as f32, 0.0]
            })
        })
        .collect();
    Ok(Some(PatternView { image_points: centres.iter().map(|p| [p.x, p.y]).collect(), object_points }))
}

/// An 8-bit gray image in OpenCV's layout.
#[derive(Debug)]
pub struct GrayImage {
    mat: Mat,
    /// Width (px).
    pub width: u32,
    /// Height (px).
    pub height: u32,
}

impl GrayImage {
    /// The OpenCV matrix (8-bit, one channel).
    pub fn mat(&self) -> &Mat {
        &self.mat
    }
}

/// An image file as 8-bit gray (colour files are converted as OpenCV's
/// `cvtColor(BGR2GRAY)` does).
pub fn read_gray(path: &Path) -> Result<GrayImage, CalibrationError> {
    let unreadable = || CalibrationError::UnreadableImage { path: path.to_path_buf() };
    // A missing file or a directory fails to read.
    let bytes = std::fs::read(path).map_err(|_| unreadable())?;
    // JPEG or PNG as `imread`'s colour, then `RGB2GRAY`: the same gray as
    // `BGR2GRAY` on `imread`'s BGR.
    let colour = crate::codec::decode(&bytes, PixelFormat::Rgb8).map_err(|_| unreadable())?;
    let mat = gray_mat(&colour)?;
    Ok(GrayImage { mat, width: colour.width, height: colour.height })
}

/// A camera image as an OpenCV 8-bit gray matrix (copied).
pub fn gray_mat(image: &Image) -> Result<Mat, CalibrationError> {
    let (rows, cols) = (image.height as i32, image.width as i32);
    let expected = image.width as usize * image.height as usize * image.format.channels();
    if image.data.len() != expected {
        return Err(CalibrationError::Marker(MarkerError::BadImage {
            width: image.width,
            height: image.height,
            channels: image.format.channels(),
            expected,
            len: image.data.len(),
        }));
    }
    match image.format {
        PixelFormat::Gray8 => {
            let flat = Mat::from_slice(&image.data).cv("Mat from image")?;
            flat.reshape(1, rows).cv("Mat::reshape")?.try_clone().cv("Mat::clone")
        }
        PixelFormat::Rgb8 => {
            let flat = Mat::from_slice(&image.data).cv("Mat from image")?;
            let rgb = flat.reshape(3, rows).cv("Mat::reshape")?;
            let mut gray = Mat::default();
            imgproc::cvt_color_def(&rgb, &mut gray, imgproc::COLOR_RGB2GRAY).cv("cvtColor")?;
            debug_assert_eq!(gray.cols(), cols);
            Ok(gray)
        }
    }
}

/// Which intrinsics `calibrateCamera` keeps fixed.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CalibrateOptions {
    /// `fx = fy` (`CALIB_FIX_ASPECT_RATIO` starting from 1).
    pub fix_aspect_ratio: bool,
    /// `p1 = p2 = 0` (`CALIB_ZERO_TANGENT_DIST`).
    pub zero_tangent: bool,
    /// `k3 = 0` (`CALIB_FIX_K3`).
    pub fix_k3: bool,
}

/// The result of a calibration.
#[derive(Clone, Debug, PartialEq)]
pub struct Calibration {
    /// The intrinsics found.
    pub intrinsics: CameraIntrinsics,
    /// RMS reprojection error over all points of all views (px).
    pub rms_px: f64,
    /// RMS reprojection error per view, in the order given (px).
    pub per_view_rms_px: Vec<f64>,
}

/// Fewest views [`calibrate`] accepts.
pub const MIN_VIEWS: usize = 3;

/// `calibrateCamera` on `views` of an image of `width x height` px (30
/// iterations of Levenberg-Marquardt or a change below `f64::EPSILON`, as
/// OpenCV's default).
pub fn calibrate(
    views: &[PatternView],
    width: u32,
    height: u32,
    options: CalibrateOptions,
) -> Result<Calibration, CalibrationError> {
    if views.len() < MIN_VIEWS {
        return Err(CalibrationError::TooFewViews {
            pattern: "the pattern".into(),
            found: views.len(),
            total: views.len(),
            needed: MIN_VIEWS,
            without_pattern: Vec::new(),
        });
    }
    let object: Vector<Vector<Point3f>> = views
        .iter()
        .map(|v| v.object_points.iter().map(|p| Point3f::new(p[0], p[1], p[2])).collect())
        .collect();
    let image: Vector<Vector<Point2f>> =
        views.iter().map(|v| v.image_points.iter().map(|p| Point2f::new(p[0], p[1])).collect()).collect();
    let mut flags = 0;
    let mut camera_matrix = Mat::eye(3, 3, core::CV_64F).cv("Mat::eye")?.to_mat().cv("Mat::eye")?;
    if options.fix_aspect_ratio {
        flags |= calib3d::CALIB_FIX_ASPECT_RATIO;
    }
    if options.zero_tangent {
        flags |= calib3d::CALIB_ZERO_TANGENT_DIST;
    }
    if options.fix_k3 {
        flags |= calib3d::CALIB_FIX_K3;
    }
    let mut distortion = Mat::zeros(5, 1, core::CV_64F).cv("Mat::zeros")?.to_mat().cv("Mat::zeros")?;
    let (mut rvecs, mut tvecs) = (Vector::<Mat>::new(), Vector::<Mat>::new());
    let (mut std_intrinsics, mut std_extrinsics, mut per_view) =
        (Mat::default(), Mat::default(), Mat::default());
    let criteria = TermCriteria::new(core::TermCriteria_COUNT + core::TermCriteria_EPS, 30, f64::EPSILON)
        .cv("TermCriteria")?;
    let rms_px = calib3d::calibrate_camera_extended(
        &object,
        &image,
        Size::new(width as i32, height as i32),
        &mut camera_matrix,
        &mut distortion,
        &mut rvecs,
        &mut tvecs,
        &mut std_intrinsics,
        &mut std_extrinsics,
        &mut per_view,
        flags,
        criteria,
    )
    .cv("calibrateCamera")?;
    let k = values(&camera_matrix)?;
    let d = values(&distortion)?;
    let mut dist = [0.0; 5];
    dist.iter_mut().zip(&d).for_each(|(o, v)| *o = *v);
    let intrinsics =
        CameraIntrinsics { width, height, fx: k[0], fy: k[4], cx: k[2], cy: k[5], distortion: dist };
    let usable = [intrinsics.fx, intrinsics.fy, rms_px].iter().all(|v| v.is_finite())
        && intrinsics.fx > 0.0
        && intrinsics.fy > 0.0;
    if !usable {
        return Err(CalibrationError::Diverged { fx: intrinsics.fx, fy: intrinsics.fy, rms_px });
    }
    Ok(Calibration { intrinsics, rms_px, per_view_rms_px: values(&per_view)? })
}

fn values(m: &Mat) -> Result<Vec<f64>, CalibrationError> {
    let mut as_f64 = Mat::default();
    m.convert_to(&mut as_f64, core::CV_64F, 1.0, 0.0).cv("Mat::convert_to")?;
    let contiguous = as_f64.try_clone().cv("Mat::clone")?;
    Ok(contiguous.data_typed::<f64>().cv("Mat::data_typed")?.to_vec())
}

impl FromStr for Pattern {
    type Err = CalibrationError;

    fn from_str(spec: &str) -> Result<Pattern, CalibrationError> {
        pattern::parse(spec)
    }
}

#[cfg(test)]
#[path = "calibrate_tests.rs"]
mod tests;
