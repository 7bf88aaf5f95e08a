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

    /// A non-identity orientation turning about the camera's z axis: the
    /// state's orientation after 1 s is `Rz(1.5 rad) R_0` (the angular
    /// velocity is in the camera frame, a left product). Checked with
    /// rotation matrices, independently of the quaternion code; the right
    /// product `R_0 Rz(1.5)` is 58 degrees away.
    #[test]
    fn the_angular_velocity_turns_a_tilted_object_about_the_camera_axes() {
        let r0 = UnitQuaternion::from_euler_angles(0.3, -0.7, 1.1);
        let omega = Vector3::new(0.0, 0.0, 1.5);
        let mut x = state_from_pose(&PoseVelocity {
            camera_from_object: Isometry3::from_parts(Translation3::new(0.0, 0.0, 0.7), r0),
            linear_velocity_mps: Vector3::zeros(),
            angular_velocity_radps: omega,
        });
        for _ in 0..30 {
            x = motion(&x, &DVector::zeros(9), 1.0 / 30.0);
        }
        let r = pose_velocity(&x).camera_from_object.rotation.to_rotation_matrix();
        let rz = nalgebra::Rotation3::from_axis_angle(&Vector3::z_axis(), 1.5);
        let left = rz * r0.to_rotation_matrix();
        let right = r0.to_rotation_matrix() * rz;
        assert_relative_eq!(r.matrix(), left.matrix(), epsilon = 1e-12);
        assert!(r.angle_to(&right).to_degrees() > 45.0, "{}", r.angle_to(&right).to_degrees());
    }

    /// A prior at a tilted orientation, uncertain about the camera's x axis
    /// (0.1 rad²) and sure about y and z (1e-4 rad²), corrected with a pose
    /// whose orientation is turned by 0.02 rad about camera x and 0.02 rad
    /// about camera y (`R_q = 1e-3`): the posterior is the Kalman update of
    /// the rotation vector in camera axes, `δ = P (P + R)^-1 (0.02, 0.02, 0)`,
    /// so it moves 0.0198 rad about x and 0.0018 rad about y. Uncertainty
    /// about the object's own x axis (a right product) would move it about
    /// another axis.
    #[test]
    fn a_pose_correction_is_the_kalman_update_in_camera_axes() {
        use crate::ukf::{Belief, UtParams, correct};
        let q0 = UnitQuaternion::from_euler_angles(0.9, 0.4, -1.2);
        let p0 = Vector3::new(0.05, -0.02, 0.8);
        let prior_pose = PoseVelocity::at_rest(Isometry3::from_parts(Translation3::from(p0), q0));
        let mut cov = DMatrix::from_diagonal_element(12, 12, 1e-6);
        let (var_x, var_y, var_z) = (0.1, 1e-4, 1e-4);
        cov[(6, 6)] = var_x;
        cov[(7, 7)] = var_y;
        cov[(8, 8)] = var_z;
        let prior = Belief::new(state_from_pose(&prior_pose), cov).unwrap();
        let turn = Vector3::new(0.02, 0.02, 0.0);
        let measured_rotation = UnitQuaternion::from_scaled_axis(turn) * q0;
        let z = measurement(
            MeasuredParts::Pose,
            Some(&Isometry3::from_parts(Translation3::from(p0), measured_rotation)),
            None,
        )
        .unwrap();
        let r = [1e-3, 1e-3, 1.0, 1.0];
        let R = measurement_noise(MeasuredParts::Pose, &r);
        let posterior =
            correct(&prior, &z, &R, |x, nu| measure(MeasuredParts::Pose, x, nu), &UtParams::default())
                .unwrap()
                .posterior;
        let q = pose_velocity(&posterior.mean).camera_from_object.rotation;
        let moved_in_camera = (q * q0.inverse()).scaled_axis();
        let expected = Vector3::new(turn.x * var_x / (var_x + r[1]), turn.y * var_y / (var_y + r[1]), 0.0);
        assert_relative_eq!(moved_in_camera, expected, epsilon = 2e-5);
        for (k, var) in [var_x, var_y, var_z].into_iter().enumerate() {
            assert_relative_eq!(
                posterior.cov[(6 + k, 6 + k)],
                var * r[1] / (var + r[1]),
                max_relative = 1e-3
            );
        }
    }

    /// The UKF prediction of a tilted, spinning object against Monte Carlo:
    /// 20000 draws of the prior (orientation perturbed in camera axes, the
    /// angular velocity with it), each turned for one step with rotation
    /// matrices; the orientations' spread about the UKF's mean matches the
    /// UKF's covariance and averages to it (no bias).
    #[test]
    fn the_predicted_orientation_matches_monte_carlo_moments() {
        use crate::ukf::{Belief, UtParams, predict};
        let q0 = UnitQuaternion::from_euler_angles(-0.5, 1.0, 0.3);
        let omega0 = Vector3::new(2.0, -1.0, 3.0);
        let dt = 0.1;
        let mean = state_from_pose(&PoseVelocity {
            camera_from_object: Isometry3::from_parts(Translation3::new(0.0, 0.0, 0.7), q0),
            linear_velocity_mps: Vector3::zeros(),
            angular_velocity_radps: omega0,
        });
        let mut cov = DMatrix::from_diagonal_element(12, 12, 1e-6);
        let (sd_q, sd_w) = (Vector3::new(0.15, 0.02, 0.05), Vector3::new(0.5, 1.5, 0.2));
        for k in 0..3 {
            cov[(6 + k, 6 + k)] = sd_q[k] * sd_q[k];
            cov[(9 + k, 9 + k)] = sd_w[k] * sd_w[k];
        }
        let prior = Belief::new(mean, cov).unwrap();
        let Q = DMatrix::from_diagonal_element(9, 9, 1e-12);
        let predicted = predict(&prior, &Q, |x, w| motion(x, w, dt), &UtParams::default()).unwrap();
        let ukf_rotation = pose_velocity(&predicted.mean).camera_from_object.rotation.to_rotation_matrix();

        let mut rng = 0x5eed_u64;
        let mut normal = || {
            let mut uniform = || {
                rng = crate::maskukf::splitmix64(rng);
                ((rng >> 11) as f64 + 0.5) / (1u64 << 53) as f64
            };
            let (a, b) = (uniform(), uniform());
            (-2.0 * a.ln()).sqrt() * (std::f64::consts::TAU * b).cos()
        };
        let n = 20_000;
        let (mut sum, mut sum_sq) = (Vector3::zeros(), nalgebra::Matrix3::zeros());
        for _ in 0..n {
            let xi = Vector3::new(normal(), normal(), normal()).component_mul(&sd_q);
            let w = omega0 + Vector3::new(normal(), normal(), normal()).component_mul(&sd_w);
            let r = nalgebra::Rotation3::from_scaled_axis(w * dt)
                * nalgebra::Rotation3::from_scaled_axis(xi)
                * q0.to_rotation_matrix();
            let e = (r * ukf_rotation.inverse()).scaled_axis();
            sum += e;
            sum_sq += e * e.transpose();
        }
        let mc_mean = sum / f64::from(n);
        let mc_cov = sum_sq / f64::from(n) - mc_mean * mc_mean.transpose();
        let ukf_cov = predicted.cov.fixed_view::<3, 3>(6, 6).into_owned();
        println!("Monte Carlo mean {mc_mean:?}\ncovariance {mc_cov:?}\nUKF {ukf_cov:?}");
        // Standard error of the mean: about 0.16 / sqrt(20000) = 0.001 rad.
        assert!(mc_mean.norm() < 0.005, "{mc_mean:?}");
        for r in 0..3 {
            for c in 0..3 {
                let scale = (ukf_cov[(r, r)] * ukf_cov[(c, c)]).sqrt();
                assert!(
                    (mc_cov[(r, c)] - ukf_cov[(r, c)]).abs() < 0.08 * scale,
                    "({r}, {c}): {mc_cov} vs {ukf_cov}"
                );
            }
        }
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
