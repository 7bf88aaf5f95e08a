//! The object's position along the sliding axis, from marker positions.
//!
//! The object slides along one direction fixed in the hand. Its position `p`
//! (the first component of the dEKF state, eq. 6.1 of the thesis) is the
//! displacement of the marker along that direction since the first valid
//! sample, so `p` starts at 0.

use nalgebra::{Isometry3, Point3, Unit, Vector3};
use serde::{Deserialize, Serialize};
use thiserror::Error;

/// Why a sliding axis could not be built.
#[derive(Debug, Error, PartialEq)]
#[non_exhaustive]
pub enum AxisError {
    /// The axis has no usable direction.
    #[error("sliding axis {axis_in_hand:?} has zero or non-finite length")]
    ZeroAxis {
        /// The axis as given, in the hand frame.
        axis_in_hand: [f64; 3],
    },
}

/// The sliding axis and where the camera sees it from.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SlidingAxis {
    /// Camera pose in the hand frame (translation in m).
    pub hand_from_camera: Isometry3<f64>,
    /// Direction of positive sliding in the hand frame (default: down, `(0, 0, -1)`).
    pub axis_in_hand: Unit<Vector3<f64>>,
}

impl SlidingAxis {
    /// A sliding axis along `axis_in_hand` (any length, normalised here).
    pub fn new(
        hand_from_camera: Isometry3<f64>,
        axis_in_hand: Vector3<f64>,
    ) -> Result<SlidingAxis, AxisError> {
        let axis = Unit::try_new(axis_in_hand, 1e-12)
            .filter(|a| a.iter().all(|v| v.is_finite()))
            .ok_or(AxisError::ZeroAxis { axis_in_hand: axis_in_hand.into() })?;
        Ok(SlidingAxis { hand_from_camera, axis_in_hand: axis })
    }

    /// Coordinate of a point along the axis, from the hand origin (m).
    pub fn along_axis_m(&self, point_in_camera: &Point3<f64>) -> f64 {
        let point_in_hand = self.hand_from_camera * point_in_camera;
        self.axis_in_hand.dot(&point_in_hand.coords)
    }

    /// A projector whose first valid sample defines position 0.
    pub fn projector(&self) -> SlidingProjector {
        SlidingProjector { axis: self.clone(), origin_along_m: None }
    }
}

/// Maps marker positions (camera frame) to the sliding position `p` (m).
#[derive(Clone, Debug, PartialEq)]
pub struct SlidingProjector {
    axis: SlidingAxis,
    origin_along_m: Option<f64>,
}

impl SlidingProjector {
    /// Sliding position `p` (m) of a marker at `point_in_camera` (m); the
    /// first finite sample becomes `p = 0`. Non-finite points give `None` and
    /// do not define the origin.
    pub fn project(&mut self, point_in_camera: &Point3<f64>) -> Option<f64> {
        if !point_in_camera.iter().all(|v| v.is_finite()) {
            return None;
        }
        let along_m = self.axis.along_axis_m(point_in_camera);
        let origin_m = *self.origin_along_m.get_or_insert(along_m);
        Some(along_m - origin_m)
    }

    /// The marker's coordinate along the axis that defines `p = 0` (m from the
    /// hand origin), once a sample has arrived.
    pub fn origin_along_axis_m(&self) -> Option<f64> {
        self.origin_along_m
    }

    /// Forgets the origin: the next valid sample defines `p = 0` again.
    pub fn reset(&mut self) {
        self.origin_along_m = None;
    }

    /// The axis projected on.
    pub fn axis(&self) -> &SlidingAxis {
        &self.axis
    }
}

#[cfg(test)]
mod tests {
    use nalgebra::{Translation3, UnitQuaternion};

    use super::*;

    #[test]
    fn first_sample_is_zero_and_motion_along_the_axis_is_measured() {
        // Camera 0.3 m in front of the palm, looking back at it (camera z = hand -x).
        let rotation = UnitQuaternion::from_basis_unchecked(&[Vector3::y(), -Vector3::z(), -Vector3::x()]);
        let hand_from_camera = Isometry3::from_parts(Translation3::new(0.3, 0.0, 0.1), rotation);
        let axis = SlidingAxis::new(hand_from_camera, Vector3::new(0.0, 0.0, -2.0)).unwrap();
        let mut projector = axis.projector();
        let camera_from_hand = hand_from_camera.inverse();
        let at = |z: f64, y: f64| camera_from_hand * Point3::new(0.1, y, z);
        assert_eq!(projector.project(&Point3::new(f64::NAN, 0.0, 0.2)), None);
        assert_eq!(projector.origin_along_axis_m(), None);
        assert!(projector.project(&at(0.0, 0.0)).unwrap().abs() < 1e-12);
        // 2 cm down is +2 cm of sliding; sideways motion does not count.
        assert!((projector.project(&at(-0.02, 0.01)).unwrap() - 0.02).abs() < 1e-12);
        projector.reset();
        assert!(projector.project(&at(-0.02, 0.0)).unwrap().abs() < 1e-12);
    }

    #[test]
    fn a_zero_axis_is_refused() {
        let err = SlidingAxis::new(Isometry3::identity(), Vector3::zeros()).unwrap_err();
        assert_eq!(err, AxisError::ZeroAxis { axis_in_hand: [0.0; 3] });
    }
}
