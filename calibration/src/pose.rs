//! Marker pose from its four corners: `solvePnPGeneric` with `SOLVEPNP_IPPE_SQUARE`.

use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use opencv::calib3d;
use opencv::core::{Mat, MatTraitConstManual, Point2d, Point3d, Vector};
use slidetrack_core::CameraIntrinsics;

use crate::aruco::MarkerDetection;
use crate::error::{MarkerError, OpenCvContext};

/// The pose of one marker.
#[derive(Clone, Debug, PartialEq)]
pub struct MarkerPose {
    /// Marker frame (OpenCV ArUco: origin at the marker centre, x right, y up
    /// as printed, z out of the marker towards the camera) in the camera frame
    /// (x right, y down, z forward); translation in m.
    pub camera_from_marker: Isometry3<f64>,
    /// Root-mean-square distance between the detected corners and the corners
    /// reprojected through the pose and the intrinsics (px).
    pub reprojection_error_px: f64,
}

/// The marker's corners in its own frame (m), in the order `SOLVEPNP_IPPE_SQUARE`
/// requires, which is also the detector's corner order: top-left, top-right,
/// bottom-right, bottom-left.
pub fn marker_corners_in_marker(marker_size_m: f64) -> [Point3<f64>; 4] {
    let h = marker_size_m / 2.0;
    [Point3::new(-h, h, 0.0), Point3::new(h, h, 0.0), Point3::new(h, -h, 0.0), Point3::new(-h, -h, 0.0)]
}

/// Pose of a detected marker of side `marker_size_m` (m, the black square,
/// border cells included) seen through `intrinsics` (distortion included):
/// the IPPE solution with the smaller reprojection error.
pub fn marker_pose(
    detection: &MarkerDetection,
    intrinsics: &CameraIntrinsics,
    marker_size_m: f64,
) -> Result<MarkerPose, MarkerError> {
    let [best, _] = marker_pose_candidates(detection, intrinsics, marker_size_m)?;
    Ok(best)
}

/// Both poses of a square planar target that explain its four corners
/// (`solvePnPGeneric` with `SOLVEPNP_IPPE_SQUARE`), the one with the smaller
/// reprojection error first. A small or nearly fronto-parallel marker is
/// ambiguous: the two tilt the other way about the same line of sight with
/// almost the same reprojection error, and the corners alone cannot tell
/// which is true (another cue can: the measured depth, another marker).
pub fn marker_pose_candidates(
    detection: &MarkerDetection,
    intrinsics: &CameraIntrinsics,
    marker_size_m: f64,
) -> Result<[MarkerPose; 2], MarkerError> {
    if !(marker_size_m.is_finite() && marker_size_m > 0.0) {
        return Err(MarkerError::BadMarkerSize { size_m: marker_size_m });
    }
    let id = detection.id;
    if detection.corners_px.iter().flatten().any(|c| !c.is_finite()) {
        return Err(MarkerError::NonFiniteCorner { id, corners_px: detection.corners_px });
    }
    let corners_in_marker = marker_corners_in_marker(marker_size_m);
    let object_points: Vector<Point3d> =
        corners_in_marker.iter().map(|p| Point3d::new(p.x, p.y, p.z)).collect();
    let image_points: Vector<Point2d> =
        detection.corners_px.iter().map(|&[u, v]| Point2d::new(u, v)).collect();
    let k = intrinsics.k();
    let camera_matrix = Mat::from_slice_2d(&[&k[0..3], &k[3..6], &k[6..9]]).cv("Mat from camera matrix")?;
    let distortion = Mat::from_slice(&intrinsics.distortion).cv("Mat from distortion")?;
    let (mut rvecs, mut tvecs) = (Vector::<Mat>::new(), Vector::<Mat>::new());
    let mut errors = Mat::default();
    let found = calib3d::solve_pnp_generic(
        &object_points,
        &image_points,
        &camera_matrix,
        &distortion,
        &mut rvecs,
        &mut tvecs,
        false,
        calib3d::SolvePnPMethod::SOLVEPNP_IPPE_SQUARE,
        &Mat::default(),
        &Mat::default(),
        &mut errors,
    )
    .cv("solvePnPGeneric")?;
    let mut poses = Vec::with_capacity(2);
    for i in 0..usize::try_from(found).unwrap_or(0).min(rvecs.len()).min(tvecs.len()) {
        let r = vector3(&rvecs.get(i).cv("solvePnPGeneric rvecs")?)?;
        let t = vector3(&tvecs.get(i).cv("solvePnPGeneric tvecs")?)?;
        if !(r.iter().chain(t.iter()).all(|v| v.is_finite())) {
            continue;
        }
        let camera_from_marker =
            Isometry3::from_parts(Translation3::from(t), UnitQuaternion::from_scaled_axis(r));
        poses.push(MarkerPose {
            camera_from_marker,
            reprojection_error_px: reprojection_error_px(
                &camera_from_marker,
                &corners_in_marker,
                detection,
                intrinsics,
            )
            .ok_or(MarkerError::NoPose { id })?,
        });
    }
    poses.sort_by(|a, b| a.reprojection_error_px.total_cmp(&b.reprojection_error_px));
    let mut poses = poses.into_iter();
    match (poses.next(), poses.next()) {
        (Some(a), Some(b)) => Ok([a, b]),
        // IPPE gives two solutions; should it give one, it is both.
        (Some(a), None) => Ok([a.clone(), a]),
        _ => Err(MarkerError::NoPose { id }),
    }
}

/// RMS distance (px) between the detected corners and the marker's corners
/// reprojected through `camera_from_marker`; `None` behind the camera.
fn reprojection_error_px(
    camera_from_marker: &Isometry3<f64>,
    corners_in_marker: &[Point3<f64>; 4],
    detection: &MarkerDetection,
    intrinsics: &CameraIntrinsics,
) -> Option<f64> {
    let mut squared = 0.0;
    for (p, &[u, v]) in corners_in_marker.iter().zip(&detection.corners_px) {
        let q = camera_from_marker * p;
        let (pu, pv) = intrinsics.project([q.x, q.y, q.z])?;
        squared += (pu - u).powi(2) + (pv - v).powi(2);
    }
    Some((squared / 4.0).sqrt())
}

/// A 3x1 (or 1x3) `f64` OpenCV vector as nalgebra.
fn vector3(m: &Mat) -> Result<Vector3<f64>, MarkerError> {
    let v = m.data_typed::<f64>().cv("Mat::data_typed")?;
    match v {
        [x, y, z] => Ok(Vector3::new(*x, *y, *z)),
        _ => Err(MarkerError::OpenCv {
            operation: "solvePnPGeneric",
            source: opencv::Error::new(
                opencv::core::StsBadSize,
                format!("expected 3 values, got {}", v.len()),
            ),
        }),
    }
}
