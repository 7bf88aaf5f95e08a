//! The MaskUKF state (4.1) `x = (p, v^m, o, ȯ)`: position (m), mixed linear
//! velocity (m/s), ZYX Euler angles `o = (φ, χ, ψ)` (rad) and their rates
//! (rad/s), all for `camera_from_object`; and the white-noise-acceleration
//! motion model (4.5)-(4.7).
#![expect(non_snake_case, reason = "matrices are named as in the thesis's equations (F, H, Q, R, P, K)")]

use nalgebra::{DMatrix, DVector, Isometry3, Translation3, UnitQuaternion, Vector3};

use crate::orientation::{Component, Composite, PoseVelocity, euler};

/// `(p, v)` Euclidean, `o` Euler angles, `ȯ` Euclidean.
pub const LAYOUT: &[Component] = &[Component::Euclidean(6), Component::Angles(3), Component::Euclidean(3)];

/// Offsets of the blocks in the 12 coordinates.
pub const P: usize = 0;
/// Offset of `v^m`.
pub const V: usize = 3;
/// Offset of `o`.
pub const O: usize = 6;
/// Offset of `ȯ`.
pub const O_DOT: usize = 9;

/// The state of a pose and mixed velocity; the Euler rates come from `ω`
/// through the inverse of (4.2) where it exists (zero rates at gimbal lock).
pub fn state_from_pose(estimate: &PoseVelocity) -> Composite {
    let mut coords = DVector::zeros(12);
    coords.fixed_rows_mut::<3>(P).copy_from(&estimate.camera_from_object.translation.vector);
    coords.fixed_rows_mut::<3>(V).copy_from(&estimate.linear_velocity_mps);
    let o = euler::zyx_from_rotation(&estimate.camera_from_object.rotation.to_rotation_matrix());
    coords.fixed_rows_mut::<3>(O).copy_from(&o);
    let rates = euler::angular_velocity_from_rates_matrix(&o)
        .try_inverse()
        .map_or_else(Vector3::zeros, |inv| inv * estimate.angular_velocity_radps);
    coords.fixed_rows_mut::<3>(O_DOT).copy_from(&rates);
    Composite::new_unchecked(LAYOUT, coords)
}

/// `camera_from_object` of a state.
pub fn camera_from_object(x: &Composite) -> Isometry3<f64> {
    let o = x.vector3_at(O);
    let rotation = UnitQuaternion::from_rotation_matrix(&euler::rotation_from_zyx(&o));
    Isometry3::from_parts(Translation3::from(x.vector3_at(P)), rotation)
}

/// Pose and mixed velocity of a state, `ω = E(o) ȯ` (4.2).
pub fn pose_velocity(x: &Composite) -> PoseVelocity {
    let o = x.vector3_at(O);
    PoseVelocity {
        camera_from_object: camera_from_object(x),
        linear_velocity_mps: x.vector3_at(V),
        angular_velocity_radps: euler::angular_velocity_from_rates_matrix(&o) * x.vector3_at(O_DOT),
    }
}

/// `F` of (4.6) for a step of `dt_s` seconds.
pub fn F(dt_s: f64) -> DMatrix<f64> {
    let mut F = DMatrix::identity(12, 12);
    for k in 0..3 {
        F[(P + k, V + k)] = dt_s;
        F[(O + k, O_DOT + k)] = dt_s;
    }
    F
}

/// `Q` of (4.7) from the power spectral densities `Q_p` ((m/s)²/s) and
/// `Q_o` ((rad/s)²/s), diagonal, for a step of `dt_s` seconds.
pub fn Q(q_p: &[f64; 3], q_o: &[f64; 3], dt_s: f64) -> DMatrix<f64> {
    let mut Q = DMatrix::zeros(12, 12);
    let (c3, c2, c1) = (dt_s.powi(3) / 3.0, dt_s.powi(2) / 2.0, dt_s);
    for k in 0..3 {
        for (pos, vel, q) in [(P, V, q_p[k]), (O, O_DOT, q_o[k])] {
            Q[(pos + k, pos + k)] = q * c3;
            Q[(pos + k, vel + k)] = q * c2;
            Q[(vel + k, pos + k)] = q * c2;
            Q[(vel + k, vel + k)] = q * c1;
        }
    }
    Q
}

/// `f(x) = F x` (4.5) with the Euler angles wrapped.
pub fn motion(x: &Composite, F: &DMatrix<f64>) -> Composite {
    let mut coords = F * x.coords();
    for k in 0..3 {
        coords[O + k] = euler::wrap(coords[O + k]);
    }
    Composite::new_unchecked(LAYOUT, coords)
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn pose_and_velocity_round_trip_through_the_state() {
        let pv = PoseVelocity {
            camera_from_object: Isometry3::from_parts(
                Translation3::new(0.1, -0.05, 0.8),
                UnitQuaternion::from_euler_angles(0.2, -0.4, 1.0),
            ),
            linear_velocity_mps: Vector3::new(0.3, 0.0, -0.1),
            angular_velocity_radps: Vector3::new(1.0, -2.0, 0.5),
        };
        let back = pose_velocity(&state_from_pose(&pv));
        assert_relative_eq!(back.camera_from_object, pv.camera_from_object, epsilon = 1e-12);
        assert_relative_eq!(back.linear_velocity_mps, pv.linear_velocity_mps, epsilon = 1e-12);
        assert_relative_eq!(back.angular_velocity_radps, pv.angular_velocity_radps, epsilon = 1e-12);
    }

    #[test]
    fn the_motion_model_integrates_constant_rates() {
        let mut x = state_from_pose(&PoseVelocity::at_rest(Isometry3::identity()));
        let mut coords = x.coords().clone();
        coords[V] = 0.5;
        coords[O_DOT] = 1.0;
        x = Composite::new(LAYOUT, coords).unwrap();
        let F = F(0.1);
        for _ in 0..40 {
            x = motion(&x, &F);
        }
        assert_relative_eq!(x.coords()[P], 2.0, epsilon = 1e-12);
        assert_relative_eq!(x.coords()[O], euler::wrap(4.0), epsilon = 1e-12);
        // Q is symmetric positive definite, scaling as dt^3, dt^2, dt.
        let Q = Q(&[0.1; 3], &[0.2; 3], 0.5);
        assert_relative_eq!(Q[(0, 0)], 0.1 * 0.125 / 3.0);
        assert_relative_eq!(Q[(0, 3)], 0.1 * 0.125);
        assert!(Q.clone().cholesky().is_some());
    }
}
