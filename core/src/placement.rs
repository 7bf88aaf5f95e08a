//! Where a camera sits in the hand frame.

use nalgebra::{Isometry3, Quaternion, Rotation3, Translation3, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};
use thiserror::Error;

/// Why a [`CameraPlacement`] gives no pose.
#[derive(Clone, Debug, Error, PartialEq)]
#[non_exhaustive]
pub enum PlacementError {
    /// The look-at placement has no defined orientation: the camera sits on
    /// its target, or the view direction is parallel to `up`.
    #[error(
        "camera look-at is degenerate: position {position_m:?} m, target {look_at_m:?} m, up {up_in_hand:?}"
    )]
    DegenerateLookAt {
        /// Camera position in the hand frame (m).
        position_m: [f64; 3],
        /// Target in the hand frame (m).
        look_at_m: [f64; 3],
        /// Up direction in the hand frame.
        up_in_hand: [f64; 3],
    },
    /// A quaternion of zero (or non-finite) norm.
    #[error("camera orientation quaternion {quaternion_xyzw:?} has no usable norm")]
    BadQuaternion {
        /// The quaternion as given, `[x, y, z, w]`.
        quaternion_xyzw: [f64; 4],
    },
}

/// Camera pose in the hand frame, as a look-at or as an explicit isometry.
///
/// TOML: `placement = { kind = "look_at", position_m = [0.3, 0.0, 0.1], look_at_m = [0.1, 0.0, 0.0], up_in_hand = [0.0, 0.0, 1.0] }`
/// or `placement = { kind = "pose", translation_m = [...], quaternion_xyzw = [...] }`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum CameraPlacement {
    /// The camera at `position_m` looks at `look_at_m`; image "up" is as close
    /// to `up_in_hand` as the view direction allows.
    LookAt {
        /// Optical centre in the hand frame (m).
        position_m: [f64; 3],
        /// The point the optical axis goes through, in the hand frame (m).
        look_at_m: [f64; 3],
        /// Direction that appears "up" in the image, in the hand frame (any length).
        up_in_hand: [f64; 3],
    },
    /// `hand_from_camera` given explicitly (camera frame: x right, y down, z forward).
    Pose {
        /// Optical centre in the hand frame (m).
        translation_m: [f64; 3],
        /// Rotation hand-from-camera as a quaternion `[x, y, z, w]` (normalised on use).
        quaternion_xyzw: [f64; 4],
    },
}

impl Default for CameraPlacement {
    /// 0.30 m in front of the palm, 0.10 m above it, looking at (0.10, 0, 0) m
    /// (the nominal grasp point) with the hand's +z up in the image.
    fn default() -> Self {
        CameraPlacement::LookAt {
            position_m: [0.30, 0.0, 0.10],
            look_at_m: [0.10, 0.0, 0.0],
            up_in_hand: [0.0, 0.0, 1.0],
        }
    }
}

impl CameraPlacement {
    /// The camera pose in the hand frame.
    pub fn hand_from_camera(&self) -> Result<Isometry3<f64>, PlacementError> {
        match *self {
            CameraPlacement::LookAt { position_m, look_at_m, up_in_hand } => {
                let degenerate = || PlacementError::DegenerateLookAt { position_m, look_at_m, up_in_hand };
                let position = Vector3::from(position_m);
                let forward = Vector3::from(look_at_m) - position;
                let up = Vector3::from(up_in_hand);
                let z_cam = forward.try_normalize(1e-9).ok_or_else(degenerate)?;
                // Image x (right) = forward x up, image y (down) = forward x right.
                let x_cam = z_cam.cross(&up).try_normalize(1e-9).ok_or_else(degenerate)?;
                let y_cam = z_cam.cross(&x_cam);
                let rotation = Rotation3::from_basis_unchecked(&[x_cam, y_cam, z_cam]);
                Ok(Isometry3::from_parts(
                    Translation3::from(position),
                    UnitQuaternion::from_rotation_matrix(&rotation),
                ))
            }
            CameraPlacement::Pose { translation_m, quaternion_xyzw } => {
                let [x, y, z, w] = quaternion_xyzw;
                let q = Quaternion::new(w, x, y, z);
                let norm = q.norm();
                if !(norm.is_finite() && norm > 1e-9) {
                    return Err(PlacementError::BadQuaternion { quaternion_xyzw });
                }
                Ok(Isometry3::from_parts(
                    Translation3::from(Vector3::from(translation_m)),
                    UnitQuaternion::from_quaternion(q),
                ))
            }
        }
    }
}
