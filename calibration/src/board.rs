//! Board pose: a GridBoard's pose from every visible marker's corners, a
//! ChArUco board's from every interpolated chessboard corner.
//!
//! Points are matched to the board's layout ([`BoardLayout`], OpenCV 4.6's
//! geometry), then `solvePnP` (`SOLVEPNP_ITERATIVE`: a homography for a
//! planar target, then Levenberg-Marquardt) and `solvePnPRefineLM` give the
//! pose of the board frame; the RMS reprojection error and the number of
//! points used come with it. ChArUco corners are interpolated by OpenCV's
//! `interpolateCornersCharuco` with the camera (the markers' board pose
//! projects each corner, `cornerSubPix` refines it), then moved by
//! [`CHARUCO_CORNER_OFFSET_PX`] into the pixel convention of the markers.
//!
//! A board has no flip ambiguity: unlike one square marker, its points are
//! spread over the plane and far from a single square's symmetry.

use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use opencv::aruco;
use opencv::calib3d;
use opencv::core::{
    Mat, MatTraitConst, MatTraitConstManual, Point2d, Point2f, Point3d, Ptr, TermCriteria, ToInputArray,
    Vector,
};
use slidetrack_core::{BoardLayout, CameraIntrinsics, Image, PixelFormat};

use crate::aruco::MarkerDetection;
use crate::error::{MarkerError, OpenCvContext};

/// What OpenCV's `interpolateCornersCharuco` adds to its corners: it refines
/// each at `corner - 0.5 px` with `cornerSubPix` and returns `refined + 0.5
/// px` (opencv_contrib 4.6.0, `modules/aruco/src/charuco.cpp`, lines 317
/// and 327; OpenCV 4.13's `CharucoDetector` does the same), so its corners
/// put pixel centres at half-integers, unlike its marker corners and the
/// intrinsics (pixel centres at integers). Subtracted here: on the simulated
/// camera, whose truth is known, the interpolated corners sit 0.45 to 0.57
/// px right of and below their true projection without it, and within 0.04
/// px of it where `cornerSubPix` is started from the truth.
pub const CHARUCO_CORNER_OFFSET_PX: f64 = 0.5;

/// Fewest points a pose is solved from (`SOLVEPNP_ITERATIVE` needs 4 on a plane).
pub const MIN_BOARD_POINTS: usize = 4;

/// Board points matched to the layout: object points (board frame, m) and
/// their image points (px).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct BoardObservation {
    /// Ids of what was matched: a GridBoard's marker ids (each gives four
    /// points, in OpenCV's corner order), a ChArUco board's corner ids (one
    /// point each).
    pub ids: Vec<u32>,
    /// The points in the board frame (m).
    pub object_m: Vec<Point3<f64>>,
    /// The same points in the image (px, distorted).
    pub image_px: Vec<[f64; 2]>,
    /// Markers of the board among the detections.
    pub markers: usize,
}

/// The pose of a board.
#[derive(Clone, Debug, PartialEq)]
pub struct BoardPose {
    /// Board frame ([`BoardLayout`]: origin at the top-left corner, x right,
    /// y down the print, z into it) in the camera frame; translation in m.
    pub camera_from_board: Isometry3<f64>,
    /// RMS distance between the points and their reprojection (px).
    pub reprojection_error_px: f64,
    /// Points the pose was solved from.
    pub points: usize,
    /// Markers of the board that were seen.
    pub markers: usize,
}

impl BoardPose {
    /// The board's centre frame (x right, y up, z out of the print, like a
    /// single marker's frame: [`BoardLayout::board_from_centre`]) in the camera frame.
    pub fn camera_from_centre(&self, layout: &BoardLayout) -> Isometry3<f64> {
        self.camera_from_board * layout.board_from_centre()
    }
}

/// A board of a dictionary: its layout and, for ChArUco, OpenCV's board
/// (for the corner interpolation).
pub struct Board {
    layout: BoardLayout,
    charuco: Option<Ptr<aruco::CharucoBoard>>,
}

impl std::fmt::Debug for Board {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Board").field("layout", &self.layout).finish()
    }
}

impl Board {
    /// The board of `layout` printed with markers of `dictionary`.
    pub(crate) fn with_opencv(
        layout: BoardLayout,
        dictionary: &Ptr<aruco::Dictionary>,
    ) -> Result<Board, MarkerError> {
        layout.validate().map_err(MarkerError::BadBoard)?;
        let charuco = match layout {
            BoardLayout::Grid { .. } => None,
            BoardLayout::Charuco { squares_x, squares_y, square_length_m, marker_length_m } => Some(
                aruco::CharucoBoard::create(
                    squares_x as i32,
                    squares_y as i32,
                    square_length_m as f32,
                    marker_length_m as f32,
                    dictionary,
                )
                .cv("CharucoBoard::create")?,
            ),
        };
        Ok(Board { layout, charuco })
    }

    /// The board of `layout` printed with markers of a predefined dictionary.
    pub fn new(layout: BoardLayout, dictionary: &crate::aruco::Dictionary) -> Result<Board, MarkerError> {
        Board::with_opencv(layout, dictionary.opencv())
    }

    /// The board of `layout` printed with markers of a predefined dictionary
    /// or of a dictionary file (the still-image tools' dictionaries).
    pub fn with_dictionary(
        layout: BoardLayout,
        dictionary: &crate::marker_tool::ToolDictionary,
    ) -> Result<Board, MarkerError> {
        Board::with_opencv(layout, dictionary.opencv())
    }

    /// A board's points in a photo (see [`Board::observe_image`]).
    pub fn observe_photo(
        &self,
        detections: &[MarkerDetection],
        photo: &crate::marker_tool::Photo,
        intrinsics: &CameraIntrinsics,
    ) -> Result<BoardObservation, MarkerError> {
        self.observe_mat(detections, photo.mat(), intrinsics)
    }

    /// The layout.
    pub fn layout(&self) -> &BoardLayout {
        &self.layout
    }

    /// A GridBoard's points: the four corners of every detected marker of
    /// the board (other ids ignored). For a ChArUco board use
    /// [`Board::observe_image`].
    pub fn observe_markers(&self, detections: &[MarkerDetection]) -> BoardObservation {
        let layout = self.layout.markers();
        let mut obs = BoardObservation::default();
        for d in detections {
            let Some(m) = layout.iter().find(|m| m.id == d.id) else { continue };
            obs.ids.push(d.id);
            obs.object_m.extend_from_slice(&m.corners_m);
            obs.image_px.extend_from_slice(&d.corners_px);
            obs.markers += 1;
        }
        obs
    }

    /// The board's points in `image` (8-bit gray or RGB) given its markers
    /// detected there: a GridBoard's marker corners, a ChArUco board's
    /// interpolated chessboard corners.
    pub fn observe_image(
        &self,
        detections: &[MarkerDetection],
        image: &Image,
        intrinsics: &CameraIntrinsics,
    ) -> Result<BoardObservation, MarkerError> {
        if self.charuco.is_none() {
            return Ok(self.observe_markers(detections));
        }
        let (rows, cols) = (image.height as i32, image.width as i32);
        let mut gray = Mat::default();
        match image.format {
            PixelFormat::Gray8 => {
                let view =
                    Mat::new_rows_cols_with_data::<u8>(rows, cols, &image.data).cv("Mat from image")?;
                view.copy_to(&mut gray).cv("Mat::copy_to")?;
            }
            PixelFormat::Rgb8 => {
                let rgb = Mat::new_rows_cols_with_bytes::<opencv::core::Vec3b>(rows, cols, &image.data)
                    .cv("Mat from image")?;
                opencv::imgproc::cvt_color(&rgb, &mut gray, opencv::imgproc::COLOR_RGB2GRAY, 0)
                    .cv("cvtColor")?;
            }
        }
        self.observe_mat(detections, &gray, intrinsics)
    }

    /// As [`Board::observe_image`], on an OpenCV image (gray or BGR).
    fn observe_mat(
        &self,
        detections: &[MarkerDetection],
        image: &impl ToInputArray,
        intrinsics: &CameraIntrinsics,
    ) -> Result<BoardObservation, MarkerError> {
        let Some(charuco) = &self.charuco else { return Ok(self.observe_markers(detections)) };
        let markers = self.observe_markers(detections).markers;
        let mut obs = BoardObservation { markers, ..BoardObservation::default() };
        let ids: Vector<i32> = detections.iter().map(|d| d.id as i32).collect();
        let corners: Vector<Vector<Point2f>> = detections
            .iter()
            .map(|d| d.corners_px.iter().map(|&[u, v]| Point2f::new(u as f32, v as f32)).collect())
            .collect();
        if ids.is_empty() {
            return Ok(obs);
        }
        let (camera_matrix, distortion) = camera_mats(intrinsics)?;
        let mut charuco_corners = Vector::<Point2f>::new();
        let mut charuco_ids = Vector::<i32>::new();
        aruco::interpolate_corners_charuco(
            &corners,
            &ids,
            image,
            charuco,
            &mut charuco_corners,
            &mut charuco_ids,
            &camera_matrix,
            &distortion,
            2,
        )
        .cv("interpolateCornersCharuco")?;
        let board_corners = self.layout.chessboard_corners_m();
        for (id, p) in charuco_ids.iter().zip(charuco_corners.iter()) {
            let Some(object) = usize::try_from(id).ok().and_then(|k| board_corners.get(k)) else { continue };
            obs.ids.push(id as u32);
            obs.object_m.push(*object);
            let [u, v] = [f64::from(p.x), f64::from(p.y)];
            obs.image_px.push([u - CHARUCO_CORNER_OFFSET_PX, v - CHARUCO_CORNER_OFFSET_PX]);
        }
        Ok(obs)
    }
}

/// The bits of every marker of `layout` in the order of
/// [`BoardLayout::markers`], for printing it (the simulator).
pub fn board_patterns(
    layout: &BoardLayout,
    dictionary: &crate::aruco::Dictionary,
) -> Result<Vec<slidetrack_core::MarkerPattern>, MarkerError> {
    layout.validate().map_err(MarkerError::BadBoard)?;
    layout.markers().iter().map(|m| dictionary.marker_pattern(m.id)).collect()
}

/// The board's pose from its matched points: `solvePnP`
/// (`SOLVEPNP_ITERATIVE`) then `solvePnPRefineLM` (at most 100 iterations,
/// or steps below 1e-10), with its RMS reprojection error.
pub fn board_pose(obs: &BoardObservation, intrinsics: &CameraIntrinsics) -> Result<BoardPose, MarkerError> {
    let points = obs.object_m.len().min(obs.image_px.len());
    if points < MIN_BOARD_POINTS {
        return Err(MarkerError::TooFewBoardPoints { points, needed: MIN_BOARD_POINTS });
    }
    if obs.image_px.iter().flatten().any(|v| !v.is_finite()) {
        return Err(MarkerError::NoBoardPose { points });
    }
    let object: Vector<Point3d> = obs.object_m.iter().map(|p| Point3d::new(p.x, p.y, p.z)).collect();
    let image: Vector<Point2d> = obs.image_px.iter().map(|&[u, v]| Point2d::new(u, v)).collect();
    let (camera_matrix, distortion) = camera_mats(intrinsics)?;
    let (mut rvec, mut tvec) = (Mat::default(), Mat::default());
    let found = calib3d::solve_pnp(
        &object,
        &image,
        &camera_matrix,
        &distortion,
        &mut rvec,
        &mut tvec,
        false,
        calib3d::SOLVEPNP_ITERATIVE,
    )
    .cv("solvePnP")?;
    if !found {
        return Err(MarkerError::NoBoardPose { points });
    }
    let criteria =
        TermCriteria::new(opencv::core::TermCriteria_COUNT + opencv::core::TermCriteria_EPS, 100, 1e-10)
            .cv("TermCriteria")?;
    calib3d::solve_pnp_refine_lm(
        &object,
        &image,
        &camera_matrix,
        &distortion,
        &mut rvec,
        &mut tvec,
        criteria,
    )
    .cv("solvePnPRefineLM")?;
    let (r, t) = (vector3(&rvec)?, vector3(&tvec)?);
    if !r.iter().chain(t.iter()).all(|v| v.is_finite()) {
        return Err(MarkerError::NoBoardPose { points });
    }
    let camera_from_board = Isometry3::from_parts(Translation3::from(t), UnitQuaternion::from_scaled_axis(r));
    let mut squared = 0.0;
    for (p, &[u, v]) in obs.object_m.iter().zip(&obs.image_px) {
        let q = camera_from_board * p;
        let (pu, pv) = intrinsics.project([q.x, q.y, q.z]).ok_or(MarkerError::NoBoardPose { points })?;
        squared += (pu - u).powi(2) + (pv - v).powi(2);
    }
    Ok(BoardPose {
        camera_from_board,
        reprojection_error_px: (squared / points as f64).sqrt(),
        points,
        markers: obs.markers,
    })
}

/// OpenCV's camera matrix and distortion vector of `intrinsics`.
fn camera_mats(intrinsics: &CameraIntrinsics) -> Result<(Mat, Mat), MarkerError> {
    let k = intrinsics.k();
    let camera_matrix = Mat::from_slice_2d(&[&k[0..3], &k[3..6], &k[6..9]]).cv("Mat from camera matrix")?;
    let distortion =
        Mat::from_slice(&intrinsics.distortion).cv("Mat from distortion")?.try_clone().cv("Mat")?;
    Ok((camera_matrix, distortion))
}

/// A 3x1 `f64` OpenCV vector as nalgebra.
fn vector3(m: &Mat) -> Result<Vector3<f64>, MarkerError> {
    let v = m.data_typed::<f64>().cv("Mat::data_typed")?;
    match v {
        [x, y, z] => Ok(Vector3::new(*x, *y, *z)),
        _ => Err(MarkerError::NoBoardPose { points: 0 }),
    }
}

#[cfg(test)]
#[path = "board_tests.rs"]
mod tests;
