//! The camera's pose in the hand frame (`hand_from_camera`) from views of a
//! target (a marker or a board) fixed to the hand at a known mount pose.
//!
//! Each accepted frame gives one estimate
//! `hand_from_camera = hand_from_target * camera_from_target⁻¹`; the result
//! is their robust average: the rotation is the chordal L2 mean (the sum of
//! the rotation matrices projected onto SO(3) by SVD), the translation the
//! arithmetic mean, after frames with a high reprojection error and frames far
//! from the first average (outliers, e.g. a flipped single-marker pose) are
//! dropped.
//!
//! The same formula serves both mountings, because both keep
//! `hand_from_camera` constant over the frames:
//! - **fixed camera** (on a stand, looking at the hand): the transform holds
//!   only while the hand does not move relative to the stand, so keep the hand
//!   still while calibrating (frames taken while the hand moves are wrong
//!   unless the hand frame is the stand's frame);
//! - **camera on the wrist** (rides with the hand): the transform is constant
//!   whatever the hand does, so frames taken while the hand moves are all
//!   usable, and several views of the target average out more noise.
//!
//! The uncertainty comes from the per-frame spread: the standard error of the
//! mean assumes independent frames (frame noise), so it does not include the
//! error of the mount pose `hand_from_target`, which enters the result 1:1.

use nalgebra::{Isometry3, Matrix3, Matrix6, Rotation3, Translation3, UnitQuaternion, Vector3, Vector6};
use serde::{Deserialize, Serialize};
use slidetrack_core::CameraPlacement;

use crate::hand_eye_error::HandEyeError;

/// One view of the hand's target.
#[derive(Clone, Debug, PartialEq)]
pub struct TargetView {
    /// The target frame in the camera frame (m), from a marker or board pose.
    pub camera_from_target: Isometry3<f64>,
    /// Root-mean-square reprojection error of that pose (px).
    pub reprojection_error_px: f64,
}

/// How frames are screened.
#[derive(Clone, Debug, PartialEq)]
pub struct HandEyeOptions {
    /// Frames whose pose reprojects worse than this are dropped (px).
    pub max_reprojection_error_px: f64,
    /// A frame further than this from the first average (translation) is an outlier (m).
    pub max_translation_deviation_m: f64,
    /// A frame turned further than this from the first average is an outlier (degrees).
    pub max_rotation_deviation_deg: f64,
    /// Fewest frames that must remain.
    pub min_frames: usize,
}

impl Default for HandEyeOptions {
    fn default() -> Self {
        HandEyeOptions {
            max_reprojection_error_px: 2.0,
            max_translation_deviation_m: 0.01,
            max_rotation_deviation_deg: 3.0,
            min_frames: 3,
        }
    }
}

/// The estimated camera pose in the hand frame and its uncertainty.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct HandCalibration {
    /// Optical centre in the hand frame (m).
    pub translation_m: [f64; 3],
    /// Rotation hand-from-camera, `[x, y, z, w]`.
    pub quaternion_xyzw: [f64; 4],
    /// Frames averaged.
    pub frames_used: usize,
    /// Frames dropped for their reprojection error.
    pub frames_rejected_reprojection: usize,
    /// Frames dropped as outliers.
    pub frames_rejected_outlier: usize,
    /// Standard error of the translation (norm of the per-axis errors, mm).
    pub translation_std_error_mm: f64,
    /// Root-mean-square distance of the frames' translations from the mean (mm).
    pub translation_spread_mm: f64,
    /// Standard error of the rotation (norm of the per-axis errors, degrees).
    pub rotation_std_error_deg: f64,
    /// Root-mean-square angle of the frames' rotations from the mean (degrees).
    pub rotation_spread_deg: f64,
    /// Covariance of the estimate, row-major 6x6 over `[tx, ty, tz]` (m, hand
    /// frame) and `[rx, ry, rz]` (rad, rotation vector of
    /// `mean⁻¹ * frame` in the camera frame).
    pub covariance: [[f64; 6]; 6],
}

impl HandCalibration {
    /// `hand_from_camera` as an isometry.
    pub fn hand_from_camera(&self) -> Isometry3<f64> {
        let [x, y, z, w] = self.quaternion_xyzw;
        Isometry3::from_parts(
            Translation3::from(Vector3::from(self.translation_m)),
            UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(w, x, y, z)),
        )
    }

    /// The result as a `[camera] placement`.
    pub fn placement(&self) -> CameraPlacement {
        CameraPlacement::Pose { translation_m: self.translation_m, quaternion_xyzw: self.quaternion_xyzw }
    }

    /// The ready-to-paste TOML line `placement = { kind = "pose", ... }`.
    pub fn placement_toml(&self) -> String {
        let [tx, ty, tz] = self.translation_m;
        let [x, y, z, w] = self.quaternion_xyzw;
        format!(
            "placement = {{ kind = \"pose\", translation_m = [{tx:.6}, {ty:.6}, {tz:.6}], quaternion_xyzw = [{x:.8}, {y:.8}, {z:.8}, {w:.8}] }}"
        )
    }
}

/// Estimates `hand_from_camera` from views of a target mounted on the hand at
/// `hand_from_target` (see the module documentation for the method).
pub fn estimate_hand_from_camera(
    hand_from_target: &Isometry3<f64>,
    views: &[TargetView],
    options: &HandEyeOptions,
) -> Result<HandCalibration, HandEyeError> {
    let good: Vec<Isometry3<f64>> = views
        .iter()
        .filter(|v| {
            v.reprojection_error_px.is_finite()
                && v.reprojection_error_px <= options.max_reprojection_error_px
        })
        .filter(|v| v.camera_from_target.translation.vector.iter().all(|c| c.is_finite()))
        .map(|v| hand_from_target * v.camera_from_target.inverse())
        .collect();
    let rejected_reprojection = views.len() - good.len();
    let need = options.min_frames.max(1);
    if good.len() < need {
        return Err(HandEyeError::TooFewFrames { usable: good.len(), needed: need, total: views.len() });
    }
    let first = average(&good);
    let max_angle_rad = options.max_rotation_deviation_deg.to_radians();
    let kept: Vec<Isometry3<f64>> = good
        .iter()
        .filter(|p| {
            (p.translation.vector - first.translation.vector).norm() <= options.max_translation_deviation_m
                && p.rotation.angle_to(&first.rotation) <= max_angle_rad
        })
        .copied()
        .collect();
    if kept.len() < need {
        return Err(HandEyeError::TooManyOutliers { kept: kept.len(), needed: need, usable: good.len() });
    }
    let mean = average(&kept);
    Ok(summarise(&mean, &kept, rejected_reprojection, good.len() - kept.len()))
}

/// Chordal L2 mean of the rotations (SVD projection of the summed matrices)
/// and arithmetic mean of the translations.
fn average(poses: &[Isometry3<f64>]) -> Isometry3<f64> {
    let n = poses.len() as f64;
    let sum: Matrix3<f64> = poses.iter().map(|p| *p.rotation.to_rotation_matrix().matrix()).sum();
    let translation: Vector3<f64> = poses.iter().map(|p| p.translation.vector).sum::<Vector3<f64>>() / n;
    let rotation = nearest_rotation(&sum);
    Isometry3::from_parts(Translation3::from(translation), UnitQuaternion::from_rotation_matrix(&rotation))
}

/// The rotation nearest to `m` in the Frobenius norm (`U diag(1, 1, det) Vᵀ`).
fn nearest_rotation(m: &Matrix3<f64>) -> Rotation3<f64> {
    let svd = m.svd(true, true);
    let (Some(u), Some(v_t)) = (svd.u, svd.v_t) else {
        return Rotation3::identity();
    };
    let d = (u * v_t).determinant().signum();
    let r = u * Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, d)) * v_t;
    Rotation3::from_matrix_unchecked(r)
}

fn summarise(
    mean: &Isometry3<f64>,
    kept: &[Isometry3<f64>],
    by_reprojection: usize,
    outliers: usize,
) -> HandCalibration {
    let n = kept.len() as f64;
    let residuals: Vec<Vector6<f64>> = kept
        .iter()
        .map(|p| {
            let dt = p.translation.vector - mean.translation.vector;
            let dr = (mean.rotation.inverse() * p.rotation).scaled_axis();
            Vector6::new(dt.x, dt.y, dt.z, dr.x, dr.y, dr.z)
        })
        .collect();
    let scatter: Matrix6<f64> = residuals.iter().map(|r| r * r.transpose()).sum();
    // Sample covariance of a frame, then of the mean of n frames.
    let per_frame = if kept.len() > 1 { scatter / (n - 1.0) } else { Matrix6::zeros() };
    let of_mean = per_frame / n;
    let t_se_m = (of_mean[(0, 0)] + of_mean[(1, 1)] + of_mean[(2, 2)]).sqrt();
    let r_se_rad = (of_mean[(3, 3)] + of_mean[(4, 4)] + of_mean[(5, 5)]).sqrt();
    let t_spread_m = (residuals.iter().map(|r| r.fixed_rows::<3>(0).norm_squared()).sum::<f64>() / n).sqrt();
    let r_spread_rad =
        (residuals.iter().map(|r| r.fixed_rows::<3>(3).norm_squared()).sum::<f64>() / n).sqrt();
    let q = mean.rotation.coords;
    let mut covariance = [[0.0; 6]; 6];
    for (i, row) in covariance.iter_mut().enumerate() {
        for (j, c) in row.iter_mut().enumerate() {
            *c = of_mean[(i, j)];
        }
    }
    HandCalibration {
        translation_m: mean.translation.vector.into(),
        quaternion_xyzw: [q.x, q.y, q.z, q.w],
        frames_used: kept.len(),
        frames_rejected_reprojection: by_reprojection,
        frames_rejected_outlier: outliers,
        translation_std_error_mm: t_se_m * 1e3,
        translation_spread_mm: t_spread_m * 1e3,
        rotation_std_error_deg: r_se_rad.to_degrees(),
        rotation_spread_deg: r_spread_rad.to_degrees(),
        covariance,
    }
}

/// Translation (mm) and rotation (degrees) between two poses.
pub fn pose_difference(a: &Isometry3<f64>, b: &Isometry3<f64>) -> (f64, f64) {
    let mm = (a.translation.vector - b.translation.vector).norm() * 1e3;
    (mm, a.rotation.angle_to(&b.rotation).to_degrees())
}

#[cfg(test)]
#[path = "hand_eye_tests.rs"]
mod tests;
