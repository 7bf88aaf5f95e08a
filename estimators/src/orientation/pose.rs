//! [`PoseVelocity`]: what the vision trackers estimate for an object.

use nalgebra::{Isometry3, Vector3};

/// The pose and mixed velocity `(ṗ, ω)` of an object (thesis (3.25)/(3.27)),
/// all in the camera frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PoseVelocity {
    /// `camera_from_object` (m).
    pub camera_from_object: Isometry3<f64>,
    /// `ṗ`: velocity of the object frame's origin, camera frame (m/s).
    pub linear_velocity_mps: Vector3<f64>,
    /// `ω`: angular velocity, camera frame (rad/s).
    pub angular_velocity_radps: Vector3<f64>,
}

impl PoseVelocity {
    /// At rest at `camera_from_object`.
    pub fn at_rest(camera_from_object: Isometry3<f64>) -> PoseVelocity {
        PoseVelocity {
            camera_from_object,
            linear_velocity_mps: Vector3::zeros(),
            angular_velocity_radps: Vector3::zeros(),
        }
    }

    /// The spatial velocity `𝒱 = (ṗ + ω × (-p), ω)` (3.26) of this mixed velocity.
    pub fn spatial_linear_velocity_mps(&self) -> Vector3<f64> {
        let p = self.camera_from_object.translation.vector;
        self.linear_velocity_mps + self.angular_velocity_radps.cross(&(-p))
    }

    /// Every number is finite.
    pub fn is_finite(&self) -> bool {
        let h = self.camera_from_object.to_homogeneous();
        h.iter()
            .chain(self.linear_velocity_mps.iter())
            .chain(self.angular_velocity_radps.iter())
            .all(|v| v.is_finite())
    }
}
