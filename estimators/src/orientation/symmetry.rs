//! Rotational symmetries of an object's shape and the rotation error that
//! discounts them (thesis Sec. 4.2.4: for objects of a purely cylindrical
//! shape the part of the angular error about the symmetry axis is left out,
//! since a tracker that sees depth only cannot tell those rotations apart).

use nalgebra::{Isometry3, Unit, Vector3};

/// A continuous rotational symmetry of a shape, or none.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum Symmetry {
    /// No symmetry taken into account.
    #[default]
    None,
    /// The shape is unchanged by any rotation about this axis (object
    /// frame): a cylinder, a can, a bowl.
    Axis {
        /// The axis direction in the object frame.
        axis_in_object: Unit<Vector3<f64>>,
    },
}

/// The rotation error (deg) between `estimate` and `truth`
/// (`camera_from_object`) once rotations that `symmetry` makes
/// indistinguishable are discounted: for an axis `a`, the smallest angle of
/// `R_gt^T R R_a(θ)` over all `θ`, which is the angle between the axis as
/// placed by the truth and by the estimate, `∠(R_gt a, R a)`; without a
/// symmetry, the plain error of (3.46).
pub fn rotation_error_modulo_symmetry_deg(
    estimate: &Isometry3<f64>,
    truth: &Isometry3<f64>,
    symmetry: &Symmetry,
) -> f64 {
    match symmetry {
        Symmetry::None => (truth.rotation * estimate.rotation.inverse()).angle().to_degrees(),
        Symmetry::Axis { axis_in_object } => {
            let a_truth = truth.rotation * axis_in_object.into_inner();
            let a_estimate = estimate.rotation * axis_in_object.into_inner();
            a_truth.angle(&a_estimate).to_degrees()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;
    use nalgebra::{Translation3, UnitQuaternion};

    /// A can (axis z) turned 40 degrees about its own axis and tilted 5
    /// degrees about x: only the tilt counts; the plain error counts both.
    /// The minimum over turns about the axis, searched by brute force,
    /// agrees with the closed form.
    #[test]
    fn turns_about_the_axis_are_discounted() {
        let truth = Isometry3::from_parts(
            Translation3::new(0.0, 0.1, 0.7),
            UnitQuaternion::from_euler_angles(0.4, -0.3, 1.2),
        );
        let estimate = Isometry3::from_parts(
            truth.translation,
            truth.rotation
                * UnitQuaternion::from_scaled_axis(Vector3::x() * 5f64.to_radians())
                * UnitQuaternion::from_scaled_axis(Vector3::z() * 40f64.to_radians()),
        );
        let can = Symmetry::Axis { axis_in_object: Vector3::z_axis() };
        assert_relative_eq!(rotation_error_modulo_symmetry_deg(&estimate, &truth, &can), 5.0, epsilon = 1e-9);
        let plain = rotation_error_modulo_symmetry_deg(&estimate, &truth, &Symmetry::None);
        assert!(plain > 40.0, "{plain}");
        let brute = (0..3600)
            .map(|i| {
                let turn = UnitQuaternion::from_scaled_axis(Vector3::z() * (f64::from(i) * 0.1).to_radians());
                (truth.rotation.inverse() * estimate.rotation * turn).angle().to_degrees()
            })
            .fold(f64::INFINITY, f64::min);
        assert_relative_eq!(brute, 5.0, epsilon = 0.01);
    }
}
