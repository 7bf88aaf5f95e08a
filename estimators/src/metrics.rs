//! Tracking metrics (thesis Sec. 3.4): RMSE of position, rotation, linear and
//! angular velocity (3.44)-(3.48); ADD (3.49) and ADI (3.55) distances, the
//! fraction below a threshold (3.50) and the area under the accuracy curve
//! (3.51)-(3.54).
//!
//! Poses are `camera_from_object` isometries (m); velocities are the mixed
//! velocity `(ṗ, ω)` in the camera frame (m/s, rad/s), or, for ROFT's
//! velocity tracker (Table 5.3), the spatial velocity `𝒱 = (ṗ + ω × (-p), ω)`.
//! The rotation error is also given with the rotation about an object's
//! symmetry axis discounted (Sec. 4.2.4, [`rotation_error_modulo_symmetry_deg`]).

use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3, Vector6};
use serde::Serialize;

use crate::maskukf::ObjectPoints;
use crate::orientation::rotation_error_modulo_symmetry_deg;

/// The threshold of the AUC metrics used in the thesis: 10 cm.
pub const AUC_THRESHOLD_M: f64 = 0.1;

/// The root mean square of a stream of errors (eq. 3.44), accumulated one
/// error at a time: the RMSE of every score in the project.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RunningRms {
    n: usize,
    sum_sq: f64,
}

impl RunningRms {
    /// Adds one error.
    pub fn add(&mut self, error: f64) {
        self.n += 1;
        self.sum_sq += error * error;
    }

    /// Errors added.
    pub fn count(&self) -> usize {
        self.n
    }

    /// `sqrt(sum e^2 / n)`, `None` before the first error.
    pub fn rms(&self) -> Option<f64> {
        (self.n > 0).then(|| (self.sum_sq / self.n as f64).sqrt())
    }
}

/// The start of the perturbed-initialisation experiments (Sec. 4.2.3):
/// `pose` moved 5 cm along each axis and turned 10 degrees on each Euler angle.
pub fn perturbed_start(pose: &Isometry3<f64>) -> Isometry3<f64> {
    let (r, p, y) = pose.rotation.euler_angles();
    let d = 10f64.to_radians();
    Isometry3::from_parts(
        Translation3::from(pose.translation.vector + Vector3::new(0.05, 0.05, 0.05)),
        UnitQuaternion::from_euler_angles(r + d, p + d, y + d),
    )
}

/// `RMSE = sqrt(Σ e_t² / N)` (3.44); `None` for no errors or a non-finite one.
pub fn rmse(errors: &[f64]) -> Option<f64> {
    if !errors.iter().all(|e| e.is_finite()) {
        return None;
    }
    let mut rms = RunningRms::default();
    for e in errors {
        rms.add(*e);
    }
    rms.rms()
}

/// Position error `|p - p_gt|` (m) (3.45).
pub fn position_error_m(estimate: &Isometry3<f64>, truth: &Isometry3<f64>) -> f64 {
    (estimate.translation.vector - truth.translation.vector).norm()
}

/// Rotation error `|log(R_gt R^T)^∨|` in degrees (3.46): the angle of the
/// relative rotation, in `[0, 180]`.
pub fn rotation_error_deg(estimate: &Isometry3<f64>, truth: &Isometry3<f64>) -> f64 {
    (truth.rotation * estimate.rotation.inverse()).angle().to_degrees()
}

/// Velocity error `|v - v_gt|` (3.47) (or, for angular velocities in rad/s,
/// convert with [`f64::to_degrees`] for (3.48)).
pub fn vector_error(estimate: &Vector3<f64>, truth: &Vector3<f64>) -> f64 {
    (estimate - truth).norm()
}

/// ADD (3.49): the mean distance between the model points placed at the
/// estimated and at the true pose (m).
pub fn add_m(estimate: &Isometry3<f64>, truth: &Isometry3<f64>, model: &ObjectPoints) -> f64 {
    let points = model.points();
    let sum: f64 = points.iter().map(|a| (truth * a - estimate * a).norm()).sum();
    sum / points.len() as f64
}

/// ADI (3.55): the mean over model points at the true pose of the distance to
/// the nearest model point at the estimated pose (m). The nearest point is
/// found in the object frame: `min_k |a_j^gt - T A_k| = min_k |T^-1 a_j^gt - A_k|`.
pub fn adi_m(estimate: &Isometry3<f64>, truth: &Isometry3<f64>, model: &ObjectPoints) -> f64 {
    let estimate_from_truth = estimate.inverse() * truth;
    let points = model.points();
    let sum: f64 = points
        .iter()
        .map(|a| {
            let q: Point3<f64> = estimate_from_truth * a;
            (model.nearest(&q) - q).norm()
        })
        .sum();
    sum / points.len() as f64
}

/// The fraction of distances below `threshold` (3.50), in `[0, 1]`.
pub fn fraction_below(distances: &[f64], threshold: f64) -> f64 {
    if distances.is_empty() {
        return 0.0;
    }
    distances.iter().filter(|d| **d < threshold).count() as f64 / distances.len() as f64
}

/// The area under the accuracy curve (3.51)-(3.54), normalised to `[0, 1]`:
/// the distances at most `threshold` sorted, the curve through `(0, 0)`,
/// `(d_i, i/N)` and `(threshold, k/N)`, integrated with rectangles whose
/// height is the accuracy at their right end (the YCB-Video toolbox's VOCap
/// rule, which the thesis tables use). It exceeds the exact integral of the
/// step-shaped empirical curve by at most `1/N`. Non-finite distances count
/// as above the threshold.
pub fn auc(distances: &[f64], threshold: f64) -> f64 {
    let n = distances.len();
    if n == 0 || !threshold.is_finite() || threshold <= 0.0 {
        return 0.0;
    }
    let mut below: Vec<f64> =
        distances.iter().copied().filter(|d| d.is_finite() && *d <= threshold).collect();
    below.sort_by(f64::total_cmp);
    let mut area = 0.0;
    let mut previous = 0.0;
    for (i, d) in below.iter().enumerate() {
        area += (d - previous) * (i + 1) as f64 / n as f64;
        previous = *d;
    }
    area += (threshold - previous) * below.len() as f64 / n as f64;
    area / threshold
}

/// One frame of a tracked sequence and its ground truth.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrameEvaluation {
    /// Estimated `camera_from_object`.
    pub estimate: Isometry3<f64>,
    /// True `camera_from_object`.
    pub truth: Isometry3<f64>,
    /// Estimated and true linear velocity `ṗ` (m/s, camera frame), if known.
    pub linear_velocity_mps: Option<(Vector3<f64>, Vector3<f64>)>,
    /// Estimated and true angular velocity `ω` (rad/s, camera frame), if known.
    pub angular_velocity_radps: Option<(Vector3<f64>, Vector3<f64>)>,
    /// The velocity tracker's spatial velocity `𝒱 = (v, ω)` (m/s, rad/s,
    /// camera frame) and the true one, when the tracker has one (ROFT).
    pub flow_velocity: Option<(Vector6<f64>, Vector6<f64>)>,
}

/// The metrics of one tracked sequence (the units of the thesis tables).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct SequenceMetrics {
    /// Frames evaluated.
    pub frames: usize,
    /// ADD-AUC at 10 cm, percent.
    pub add_auc_percent: f64,
    /// ADI-AUC at 10 cm, percent.
    pub adi_auc_percent: f64,
    /// Position RMSE (3.45), cm.
    pub position_rmse_cm: f64,
    /// Rotation RMSE (3.46), degrees.
    pub rotation_rmse_deg: f64,
    /// Rotation RMSE with the rotation about the object's symmetry axis
    /// discounted (Sec. 4.2.4), degrees; `rotation_rmse_deg` for objects
    /// without one.
    pub rotation_rmse_modulo_symmetry_deg: f64,
    /// Linear velocity RMSE (3.47), cm/s, when velocities are known.
    pub linear_velocity_rmse_cmps: Option<f64>,
    /// Angular velocity RMSE (3.48), deg/s, when velocities are known.
    pub angular_velocity_rmse_degps: Option<f64>,
    /// Linear part of the velocity tracker's `𝒱` (ROFT, Table 5.3): RMSE
    /// against the true spatial velocity, cm/s, when every frame has one.
    pub flow_linear_velocity_rmse_cmps: Option<f64>,
    /// Angular part of the velocity tracker's `𝒱` (Table 5.3): RMSE, deg/s.
    pub flow_angular_velocity_rmse_degps: Option<f64>,
    /// Largest position error, cm.
    pub max_position_error_cm: f64,
    /// Largest rotation error, degrees.
    pub max_rotation_error_deg: f64,
}

/// The errors of one frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrameErrors {
    /// ADD (m).
    pub add_m: f64,
    /// ADI (m).
    pub adi_m: f64,
    /// Position error (m).
    pub position_m: f64,
    /// Rotation error (deg).
    pub rotation_deg: f64,
    /// Rotation error without the rotation about the symmetry axis (deg).
    pub rotation_modulo_symmetry_deg: f64,
    /// Linear velocity error (m/s), when known.
    pub linear_velocity_mps: Option<f64>,
    /// Angular velocity error (rad/s), when known.
    pub angular_velocity_radps: Option<f64>,
    /// Error of the linear part of the velocity tracker's `𝒱` (m/s).
    pub flow_linear_velocity_mps: Option<f64>,
    /// Error of the angular part of the velocity tracker's `𝒱` (rad/s).
    pub flow_angular_velocity_radps: Option<f64>,
}

/// The errors of one frame against its model.
pub fn frame_errors(f: &FrameEvaluation, model: &ObjectPoints) -> FrameErrors {
    FrameErrors {
        add_m: add_m(&f.estimate, &f.truth, model),
        adi_m: adi_m(&f.estimate, &f.truth, model),
        position_m: position_error_m(&f.estimate, &f.truth),
        rotation_deg: rotation_error_deg(&f.estimate, &f.truth),
        rotation_modulo_symmetry_deg: rotation_error_modulo_symmetry_deg(
            &f.estimate,
            &f.truth,
            model.symmetry(),
        ),
        linear_velocity_mps: f.linear_velocity_mps.map(|(e, t)| vector_error(&e, &t)),
        angular_velocity_radps: f.angular_velocity_radps.map(|(e, t)| vector_error(&e, &t)),
        flow_linear_velocity_mps: f.flow_velocity.map(|(e, t)| (e - t).fixed_rows::<3>(0).norm()),
        flow_angular_velocity_radps: f.flow_velocity.map(|(e, t)| (e - t).fixed_rows::<3>(3).norm()),
    }
}

/// The metrics of frames (possibly of several sequences and objects):
/// ADD/ADI-AUC at [`AUC_THRESHOLD_M`] and the RMSEs. Velocity RMSEs are
/// `None` unless every frame has velocities.
pub fn summarize(errors: &[FrameErrors]) -> SequenceMetrics {
    let collect = |f: fn(&FrameErrors) -> f64| errors.iter().map(f).collect::<Vec<f64>>();
    let (add, adi) = (collect(|e| e.add_m), collect(|e| e.adi_m));
    let (position, rotation) = (collect(|e| e.position_m), collect(|e| e.rotation_deg));
    let linear: Option<Vec<f64>> = errors.iter().map(|e| e.linear_velocity_mps.map(|v| v * 100.0)).collect();
    let angular: Option<Vec<f64>> =
        errors.iter().map(|e| e.angular_velocity_radps.map(f64::to_degrees)).collect();
    let flow_linear: Option<Vec<f64>> =
        errors.iter().map(|e| e.flow_linear_velocity_mps.map(|v| v * 100.0)).collect();
    let flow_angular: Option<Vec<f64>> =
        errors.iter().map(|e| e.flow_angular_velocity_radps.map(f64::to_degrees)).collect();
    let rotation_modulo_symmetry = collect(|e| e.rotation_modulo_symmetry_deg);
    SequenceMetrics {
        frames: errors.len(),
        add_auc_percent: 100.0 * auc(&add, AUC_THRESHOLD_M),
        adi_auc_percent: 100.0 * auc(&adi, AUC_THRESHOLD_M),
        position_rmse_cm: rmse(&position).map_or(f64::NAN, |v| v * 100.0),
        rotation_rmse_deg: rmse(&rotation).unwrap_or(f64::NAN),
        rotation_rmse_modulo_symmetry_deg: rmse(&rotation_modulo_symmetry).unwrap_or(f64::NAN),
        linear_velocity_rmse_cmps: linear.as_deref().and_then(rmse),
        angular_velocity_rmse_degps: angular.as_deref().and_then(rmse),
        flow_linear_velocity_rmse_cmps: flow_linear.as_deref().and_then(rmse),
        flow_angular_velocity_rmse_degps: flow_angular.as_deref().and_then(rmse),
        max_position_error_cm: position.iter().fold(0.0f64, |m, v| m.max(*v)) * 100.0,
        max_rotation_error_deg: rotation.iter().fold(0.0f64, |m, v| m.max(*v)),
    }
}

/// Evaluates a sequence: [`summarize`] of the [`frame_errors`].
pub fn evaluate(frames: &[FrameEvaluation], model: &ObjectPoints) -> SequenceMetrics {
    let errors: Vec<FrameErrors> = frames.iter().map(|f| frame_errors(f, model)).collect();
    summarize(&errors)
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;
    use nalgebra::{Translation3, UnitQuaternion};

    fn cube() -> ObjectPoints {
        let mut points = Vec::new();
        for i in 0..5 {
            for j in 0..5 {
                for k in 0..5 {
                    points.push(Point3::new(
                        i as f64 * 0.02 - 0.04,
                        j as f64 * 0.02 - 0.04,
                        k as f64 * 0.02 - 0.04,
                    ));
                }
            }
        }
        ObjectPoints::new(points).unwrap()
    }

    #[test]
    fn auc_of_perfect_and_of_useless_tracks() {
        assert_relative_eq!(auc(&[0.0; 10], 0.1), 1.0);
        assert_relative_eq!(auc(&[0.2; 10], 0.1), 0.0);
        assert_relative_eq!(auc(&[], 0.1), 0.0);
        assert_relative_eq!(auc(&[f64::NAN, 0.0], 0.1), 0.5);
    }

    #[test]
    fn auc_is_within_one_over_n_of_the_exact_integral() {
        let d: Vec<f64> = (0..200).map(|i| (i as f64 * 0.61).sin().abs() * 0.15).collect();
        // Exact integral of the empirical accuracy curve: mean of max(0, 1 - d/ε).
        let exact: f64 = d.iter().map(|x| (1.0 - x / 0.1).max(0.0)).sum::<f64>() / d.len() as f64;
        let a = auc(&d, 0.1);
        assert!(a >= exact - 1e-12 && a <= exact + 1.0 / d.len() as f64, "{a} vs {exact}");
        // Hand-computed: distances 0.02, 0.06, 0.2 (N = 3): rectangles
        // 0.02 * 1/3 + 0.04 * 2/3 + 0.04 * 2/3, divided by 0.1.
        assert_relative_eq!(
            auc(&[0.06, 0.2, 0.02], 0.1),
            (0.02 / 3.0 + 0.08 * 2.0 / 3.0) / 0.1,
            epsilon = 1e-12
        );
        assert_relative_eq!(fraction_below(&[0.06, 0.2, 0.02], 0.1), 2.0 / 3.0);
    }

    #[test]
    fn add_and_adi_of_known_offsets() {
        let model = cube();
        let truth = Isometry3::from_parts(Translation3::new(0.1, 0.0, 0.6), UnitQuaternion::identity());
        let shifted = Isometry3::from_parts(Translation3::new(0.11, 0.0, 0.6), UnitQuaternion::identity());
        assert_relative_eq!(add_m(&shifted, &truth, &model), 0.01, epsilon = 1e-12);
        // A lattice rotated by 90 degrees lands on itself: ADD is large, ADI zero.
        let turned = Isometry3::from_parts(
            Translation3::new(0.1, 0.0, 0.6),
            UnitQuaternion::from_axis_angle(&Vector3::z_axis(), std::f64::consts::FRAC_PI_2),
        );
        assert!(add_m(&turned, &truth, &model) > 0.02);
        assert!(adi_m(&turned, &truth, &model) < 1e-9);
        // A shift by one lattice step: ADI counts only the uncovered face.
        assert!(adi_m(&shifted, &truth, &model) < add_m(&shifted, &truth, &model));
    }

    #[test]
    fn rmse_and_rotation_errors() {
        assert_relative_eq!(rmse(&[3.0, 4.0]).unwrap(), (12.5f64).sqrt());
        assert!(rmse(&[]).is_none());
        let a = Isometry3::identity();
        let b = Isometry3::from_parts(
            Translation3::new(0.0, 0.0, 0.0),
            UnitQuaternion::from_axis_angle(&Vector3::x_axis(), 0.5f64.to_radians() * 20.0),
        );
        assert_relative_eq!(rotation_error_deg(&b, &a), 10.0, epsilon = 1e-9);
        let frames = vec![FrameEvaluation {
            estimate: b,
            truth: a,
            linear_velocity_mps: Some((Vector3::new(0.1, 0.0, 0.0), Vector3::zeros())),
            angular_velocity_radps: None,
            flow_velocity: Some((Vector6::new(0.0, 0.03, 0.04, 0.0, 0.0, 1.0), Vector6::zeros())),
        }];
        let m = evaluate(&frames, &cube());
        assert_eq!(m.frames, 1);
        assert_relative_eq!(m.rotation_rmse_deg, 10.0, epsilon = 1e-9);
        assert_relative_eq!(m.linear_velocity_rmse_cmps.unwrap(), 10.0, epsilon = 1e-9);
        assert!(m.angular_velocity_rmse_degps.is_none());
        assert_relative_eq!(m.flow_linear_velocity_rmse_cmps.unwrap(), 5.0, epsilon = 1e-9);
        assert_relative_eq!(m.flow_angular_velocity_rmse_degps.unwrap(), 1f64.to_degrees(), epsilon = 1e-9);
        // The turn is about x: a model symmetric about x discounts all of it.
        assert_relative_eq!(m.rotation_rmse_modulo_symmetry_deg, 10.0, epsilon = 1e-9);
        let can =
            cube().with_symmetry(crate::orientation::Symmetry::Axis { axis_in_object: Vector3::x_axis() });
        assert!(evaluate(&frames, &can).rotation_rmse_modulo_symmetry_deg < 1e-6);
    }
}
