//! Stage 3 of ROFT (thesis Sec. 5.4): the pose UKF with a unit quaternion.
//!
//! State (5.10): `x = (p, v^m, q, ω)`, position (m), mixed linear velocity
//! (m/s), orientation of `camera_from_object` and angular velocity (rad/s),
//! all in the camera frame; 13 coordinates, 12 degrees of freedom.
//!
//! Motion (5.13)-(5.17): white noise acceleration for `(p, v^m)` with the
//! noise `w_v ~ N(0, Q_v)` of (5.15), quaternion kinematics
//! `q_t = exp(ω_{t-1} Δt) q_{t-1}` (the transition matrix `F_q` of (5.16) is
//! this left product), and a random walk `ω_t = ω_{t-1} + w_ω`.
//!
//! Measurements (5.11)-(5.12), (5.18): the pose `(p, q)` when a pose
//! measurement is used, and the spatial velocity `(v^m + ω × (-p), ω)` from
//! the velocity tracker; noise is added with `⊕` (on the quaternion as a
//! rotation vector).
#![expect(non_snake_case, reason = "matrices are named as in the thesis's equations (F, H, Q, R, P, K)")]

use nalgebra::{DMatrix, DVector, Isometry3, Translation3, Vector3, Vector6};

use crate::orientation::{Component, Composite, PoseVelocity, put_quaternion, quaternion};

/// `(p, v^m)` Euclidean, `q` quaternion, `ω` Euclidean.
pub const LAYOUT: &[Component] = &[Component::Euclidean(6), Component::Quaternion, Component::Euclidean(3)];
/// Offset of `p`.
pub const P: usize = 0;
/// Offset of `v^m`.
pub const V: usize = 3;
/// Offset of `q` (`x, y, z, w`).
pub const Q_OFFSET: usize = 6;
/// Offset of `ω`.
pub const W: usize = 10;

/// The state of a pose and mixed velocity.
pub fn state_from_pose(estimate: &PoseVelocity) -> Composite {
    let mut coords = DVector::zeros(13);
    coords.fixed_rows_mut::<3>(P).copy_from(&estimate.camera_from_object.translation.vector);
    coords.fixed_rows_mut::<3>(V).copy_from(&estimate.linear_velocity_mps);
    put_quaternion(&mut coords, Q_OFFSET, &estimate.camera_from_object.rotation);
    coords.fixed_rows_mut::<3>(W).copy_from(&estimate.angular_velocity_radps);
    Composite::new_unchecked(LAYOUT, coords)
}

/// Pose and mixed velocity of a state.
pub fn pose_velocity(x: &Composite) -> PoseVelocity {
    PoseVelocity {
        camera_from_object: Isometry3::from_parts(
            Translation3::from(x.vector3_at(P)),
            x.quaternion_at(Q_OFFSET),
        ),
        linear_velocity_mps: x.vector3_at(V),
        angular_velocity_radps: x.vector3_at(W),
    }
}

/// The covariance of the process noise `(w_v, w_ω)` (9 x 9): `Q_v` of (5.15)
/// from the power spectral density `Q_p` ((m/s)²/s), and `Q_ω` ((rad/s)² per
/// step), both diagonal.
pub fn process_noise(q_p: &[f64; 3], q_omega: &[f64; 3], dt_s: f64) -> DMatrix<f64> {
    let mut Q = DMatrix::zeros(9, 9);
    let (c3, c2, c1) = (dt_s.powi(3) / 3.0, dt_s.powi(2) / 2.0, dt_s);
    for k in 0..3 {
        Q[(k, k)] = q_p[k] * c3;
        Q[(k, 3 + k)] = q_p[k] * c2;
        Q[(3 + k, k)] = q_p[k] * c2;
        Q[(3 + k, 3 + k)] = q_p[k] * c1;
        Q[(6 + k, 6 + k)] = q_omega[k];
    }
    Q
}

/// `f(x, w)` of (5.13): `w = (w_v (6), w_ω (3))`.
pub fn motion(x: &Composite, w: &DVector<f64>, dt_s: f64) -> Composite {
    let c = x.coords();
    let mut coords = c.clone();
    for k in 0..3 {
        coords[P + k] = c[P + k] + c[V + k] * dt_s + w[k];
        coords[V + k] = c[V + k] + w[3 + k];
        coords[W + k] = c[W + k] + w[6 + k];
    }
    let q = quaternion::exp(&(x.vector3_at(W) * dt_s)) * x.quaternion_at(Q_OFFSET);
    put_quaternion(&mut coords, Q_OFFSET, &q);
    Composite::new_unchecked(LAYOUT, coords)
}

/// The spatial linear velocity `v^m + ω × (-p)` predicted by a state (5.18).
fn spatial_linear(x: &Composite) -> Vector3<f64> {
    x.vector3_at(V) + x.vector3_at(W).cross(&(-x.vector3_at(P)))
}

/// Which parts of (5.11) a correction uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MeasuredParts {
    /// Pose and velocity (5.11).
    PoseAndVelocity,
    /// Velocity only (5.12).
    Velocity,
    /// Pose only (the "w/o velocity" ablation).
    Pose,
}

/// Layout of the measurement `(p, q, v, ω)`.
pub const POSE_VELOCITY_LAYOUT: &[Component] =
    &[Component::Euclidean(3), Component::Quaternion, Component::Euclidean(6)];
/// Layout of the measurement `(p, q)`.
pub const POSE_LAYOUT: &[Component] = &[Component::Euclidean(3), Component::Quaternion];
/// Layout of the measurement `(v, ω)`.
pub const VELOCITY_LAYOUT: &[Component] = &[Component::Euclidean(6)];

/// The measurement vector of `parts` from a pose and a spatial velocity
/// `(v, ω)`; the unused one may be `None`.
pub fn measurement(
    parts: MeasuredParts,
    pose: Option<&Isometry3<f64>>,
    velocity: Option<&Vector6<f64>>,
) -> Option<Composite> {
    let mut coords = Vec::with_capacity(13);
    let layout = match parts {
        MeasuredParts::PoseAndVelocity => POSE_VELOCITY_LAYOUT,
        MeasuredParts::Pose => POSE_LAYOUT,
        MeasuredParts::Velocity => VELOCITY_LAYOUT,
    };
    if parts != MeasuredParts::Velocity {
        let pose = pose?;
        coords.extend_from_slice(pose.translation.vector.as_slice());
        coords.extend_from_slice(pose.rotation.coords.as_slice());
    }
    if parts != MeasuredParts::Pose {
        coords.extend_from_slice(velocity?.as_slice());
    }
    Composite::new(layout, DVector::from_vec(coords)).ok()
}

/// `h(x, ν)` of (5.18) for `parts`, `ν` ordered as `(ν_p, ν_q, ν_v, ν_ω)`
/// restricted to the parts used.
pub fn measure(parts: MeasuredParts, x: &Composite, nu: &DVector<f64>) -> Composite {
    let mut coords = Vec::with_capacity(13);
    let mut n = 0;
    let layout = match parts {
        MeasuredParts::PoseAndVelocity => POSE_VELOCITY_LAYOUT,
        MeasuredParts::Pose => POSE_LAYOUT,
        MeasuredParts::Velocity => VELOCITY_LAYOUT,
    };
    if parts != MeasuredParts::Velocity {
        let p = x.vector3_at(P) + Vector3::new(nu[0], nu[1], nu[2]);
        let q = quaternion::oplus(&x.quaternion_at(Q_OFFSET), &Vector3::new(nu[3], nu[4], nu[5]));
        coords.extend_from_slice(p.as_slice());
        coords.extend_from_slice(q.coords.as_slice());
        n = 6;
    }
    if parts != MeasuredParts::Pose {
        let v = spatial_linear(x) + Vector3::new(nu[n], nu[n + 1], nu[n + 2]);
        let w = x.vector3_at(W) + Vector3::new(nu[n + 3], nu[n + 4], nu[n + 5]);
        coords.extend_from_slice(v.as_slice());
        coords.extend_from_slice(w.as_slice());
    }
    Composite::new_unchecked(layout, DVector::from_vec(coords))
}

/// `R` for `parts`: `diag(R_p, R_q, R_v, R_ω)` restricted to the parts used.
pub fn measurement_noise(parts: MeasuredParts, r: &[f64; 4]) -> DMatrix<f64> {
    let diag: Vec<f64> = match parts {
        MeasuredParts::PoseAndVelocity => [r[0], r[1], r[2], r[3]].iter().flat_map(|v| [*v; 3]).collect(),
        MeasuredParts::Pose => [r[0], r[1]].iter().flat_map(|v| [*v; 3]).collect(),
        MeasuredParts::Velocity => [r[2], r[3]].iter().flat_map(|v| [*v; 3]).collect(),
    };
    DMatrix::from_diagonal(&DVector::from_vec(diag))
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;
    use nalgebra::UnitQuaternion;

    #[test]
    fn constant_rates_integrate_exactly_without_noise() {
        let pv = PoseVelocity {
            camera_from_object: Isometry3::from_parts(
                Translation3::new(0.0, 0.1, 0.8),
                UnitQuaternion::identity(),
            ),
            linear_velocity_mps: Vector3::new(0.3, 0.0, 0.0),
            angular_velocity_radps: Vector3::new(0.0, 0.0, 1.5),
        };
        let mut x = state_from_pose(&pv);
        let zero = DVector::zeros(9);
        for _ in 0..30 {
            x = motion(&x, &zero, 1.0 / 30.0);
        }
        let out = pose_velocity(&x);
        assert_relative_eq!(
            out.camera_from_object.translation.vector,
            Vector3::new(0.3, 0.1, 0.8),
            epsilon = 1e-12
        );
        assert_relative_eq!(out.camera_from_object.rotation.angle(), 1.5, epsilon = 1e-12);
    }

    #[test]
    fn the_predicted_velocity_measurement_is_the_spatial_velocity() {
        let pv = PoseVelocity {
            camera_from_object: Isometry3::from_parts(
                Translation3::new(0.1, 0.2, 0.7),
                UnitQuaternion::identity(),
            ),
            linear_velocity_mps: Vector3::new(0.3, -0.1, 0.05),
            angular_velocity_radps: Vector3::new(0.4, 0.0, -1.0),
        };
        let x = state_from_pose(&pv);
        let z = measure(MeasuredParts::Velocity, &x, &DVector::zeros(6));
        assert_relative_eq!(z.vector3_at(0), pv.spatial_linear_velocity_mps(), epsilon = 1e-12);
        let zp = measure(MeasuredParts::PoseAndVelocity, &x, &DVector::zeros(12));
        assert_relative_eq!(zp.vector3_at(0), pv.camera_from_object.translation.vector, epsilon = 1e-12);
        assert_eq!(
            measurement_noise(MeasuredParts::Pose, &[1.0, 2.0, 3.0, 4.0]).diagonal().as_slice(),
            &[1.0, 1.0, 1.0, 2.0, 2.0, 2.0]
        );
        assert!(measurement(MeasuredParts::Pose, None, None).is_none());
    }
}
