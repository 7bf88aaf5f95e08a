//! A tracker's belief as an odometry estimate: the pose in the parent
//! (camera) frame and the twist in the child (object) frame, each with its
//! covariance in the layout of ROS's `nav_msgs/Odometry`.
//!
//! - Pose covariance: `(x, y, z, rotation about the parent's X, Y, Z axes)`
//!   (`geometry_msgs/PoseWithCovariance`: "a fixed-axis representation").
//!   The rotation is the rotation vector `δθ` of the error on the left,
//!   `R = exp(δθ) R̂`, in the parent frame: the tangent of ROFT's quaternion
//!   `⊕` (2.114), and `δθ = E(o) δo` for MaskUKF's ZYX Euler angles (4.2).
//! - Twist covariance: `(v, ω)` of the object expressed in the object frame
//!   (`Rᵀ ṗ`, `Rᵀ ω`), as `nav_msgs/Odometry` puts the twist "in the
//!   coordinate frame given by the child_frame_id".
//!
//! Both come from one first-order propagation `Σ_y = J Σ Jᵀ` of the belief's
//! covariance `Σ` through `y(x) = (p, R(x) R̂ᵀ as a rotation vector, Rᵀ ṗ,
//! Rᵀ ω)`; `J` is taken by central differences along the belief's own
//! tangent (its `⊕`), so any state layout with a [`PoseVelocity`] works.
//! Odometry keeps no pose-twist cross-covariance: those blocks of `Σ_y` are
//! dropped.

use nalgebra::{DMatrix, Matrix6, SMatrix, Vector3, Vector6};

use super::PoseVelocity;
use super::quaternion;
use crate::EstimatorError;
use crate::ukf::Manifold;

/// Step of the central differences along each tangent direction (m, rad,
/// m/s, rad/s): small against any covariance a tracker keeps, large against
/// rounding (`y` is smooth, so the error is `O(h²)`).
const STEP: f64 = 1e-6;

/// Covariances of an odometry estimate (see the module docs for the layout).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OdometryCovariance {
    /// Of `(x, y, z, rotation about the parent's X, Y, Z)` (m², m·rad, rad²),
    /// parent (camera) frame.
    pub pose: Matrix6<f64>,
    /// Of `(v, ω)` in the child (object) frame ((m/s)², m/s·rad/s, (rad/s)²).
    pub twist_in_child: Matrix6<f64>,
}

impl OdometryCovariance {
    /// Row-major values of a 6 x 6 block, as ROS's `float64[36]`.
    pub fn row_major(m: &Matrix6<f64>) -> Vec<f64> {
        (0..6).flat_map(|r| (0..6).map(move |c| m[(r, c)])).collect()
    }
}

/// The twist of an estimate in the object frame: `(Rᵀ ṗ, Rᵀ ω)` (m/s,
/// rad/s), `R` the rotation of `camera_from_object`.
pub fn twist_in_object(estimate: &PoseVelocity) -> Vector6<f64> {
    let to_object = estimate.camera_from_object.rotation.inverse();
    let v = to_object * estimate.linear_velocity_mps;
    let w = to_object * estimate.angular_velocity_radps;
    Vector6::new(v.x, v.y, v.z, w.x, w.y, w.z)
}

/// The odometry covariances of a belief with mean `mean` and covariance
/// `cov` (`mean.dof()` square, in the tangent of `mean`'s `⊕`);
/// `pose_velocity` reads a state's pose and mixed velocity.
///
/// Errors when `cov` has the wrong size or a result is not finite.
pub fn odometry_covariance<S: Manifold>(
    mean: &S,
    cov: &DMatrix<f64>,
    pose_velocity: impl Fn(&S) -> PoseVelocity,
) -> Result<OdometryCovariance, EstimatorError> {
    let n = mean.dof();
    if cov.shape() != (n, n) {
        return Err(EstimatorError::DimensionMismatch {
            what: "odometry: belief covariance",
            expected: n,
            got: cov.nrows().max(cov.ncols()),
        });
    }
    let reference = pose_velocity(mean);
    let output = |x: &S| -> SMatrix<f64, 12, 1> {
        let e = pose_velocity(x);
        let p = e.camera_from_object.translation.vector;
        let dtheta: Vector3<f64> =
            quaternion::ominus(&e.camera_from_object.rotation, &reference.camera_from_object.rotation);
        let twist = twist_in_object(&e);
        let mut y = SMatrix::<f64, 12, 1>::zeros();
        y.fixed_rows_mut::<3>(0).copy_from(&p);
        y.fixed_rows_mut::<3>(3).copy_from(&dtheta);
        y.fixed_rows_mut::<6>(6).copy_from(&twist);
        y
    };
    let mut jacobian = DMatrix::<f64>::zeros(12, n);
    let mut delta = vec![0.0; n];
    for i in 0..n {
        delta[i] = STEP;
        let plus = output(&mean.oplus(&delta));
        delta[i] = -STEP;
        let minus = output(&mean.oplus(&delta));
        delta[i] = 0.0;
        jacobian.set_column(i, &((plus - minus) / (2.0 * STEP)));
    }
    let out = &jacobian * cov * jacobian.transpose();
    let out = (&out + out.transpose()) * 0.5;
    if !out.iter().all(|v| v.is_finite()) {
        return Err(EstimatorError::NonFiniteState { what: "odometry covariance" });
    }
    Ok(OdometryCovariance {
        pose: out.fixed_view::<6, 6>(0, 0).into_owned(),
        twist_in_child: out.fixed_view::<6, 6>(6, 6).into_owned(),
    })
}

#[cfg(test)]
#[path = "odometry_tests.rs"]
mod tests;
