//! Marker pose from its four corners: `solvePnP` with `SOLVEPNP_IPPE_SQUARE`.

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
/// border cells included) seen through `intrinsics` (distortion included).
pub fn marker_pose(
    detection: &MarkerDetection,
    intrinsics: &CameraIntrinsics,
    marker_size_m: f64,
) -> Result<MarkerPose, MarkerError> {
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
    let (mut rvec, mut tvec) = (Mat::default(), Mat::default());
    let found = calib3d::solve_pnp(
        &object_points,
        &image_points,
        &camera_matrix,
        &distortion,
        &mut rvec,
        &mut tvec,
        false,
        calib3d::SOLVEPNP_IPPE_SQUARE,
    )
    .cv("solvePnP")?;
    if !found {
        return Err(MarkerError::NoPose { id });
    }
    let r = vector3(&rvec)?;
    let t = vector3(&tvec)?;
    if !(r.iter().chain(t.iter()).all(|v| v.is_finite())) {
        return Err(MarkerError::NoPose { id });
    }
    let camera_from_marker =
        Isometry3::from_parts(Translation3::from(t), UnitQuaternion::from_scaled_axis(r));
    let mut squared = 0.0;
    for (p, &[u, v]) in corners_in_marker.iter().zip(&detection.corners_px) {
        let q = camera_from_marker * p;
        let Some((pu, pv)) = intrinsics.project([q.x, q.y, q.z]) else {
            return Err(MarkerError::NoPose { id });
        };
        squared += (pu - u).powi(2) + (pv - v).powi(2);
    }
    Ok(MarkerPose { camera_from_marker, reprojection_error_px: (squared / 4.0).sqrt() })
}

/// A 3x1 (or 1x3) `f64` OpenCV vector as nalgebra.
fn vector3(m: &Mat) -> Result<Vector3<f64>, MarkerError> {
    let v = m.data_typed::<f64>().cv("Mat::data_typed")?;
    match v {
        [x, y, z] => Ok(Vector3::new(*x, *y, *z)),
        _ => Err(MarkerError::OpenCv {
            operation: "solvePnP",
            source: opencv::Error::new(
                opencv::core::StsBadSize,
                format!("expected 3 values, got {}", v.len()),
            ),
        }),
    }
}
