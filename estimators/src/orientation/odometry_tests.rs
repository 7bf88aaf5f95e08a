use approx::assert_relative_eq;
use nalgebra::{DMatrix, DVector, Isometry3, Matrix3, Translation3, UnitQuaternion, Vector3};
use rand::SeedableRng;
use rand_distr::{Distribution, StandardNormal};

use super::*;
use crate::orientation::{Component, Composite, euler, put_quaternion};

/// ROFT's layout: `(p, v)`, a quaternion (left `⊕`), `ω`.
const QUATERNION_LAYOUT: &[Component] =
    &[Component::Euclidean(6), Component::Quaternion, Component::Euclidean(3)];
/// MaskUKF's layout: `(p, v)`, ZYX Euler angles, their rates.
const EULER_LAYOUT: &[Component] = &[Component::Euclidean(6), Component::Angles(3), Component::Euclidean(3)];

fn quaternion_state(p: [f64; 3], v: [f64; 3], rotation: &UnitQuaternion<f64>, w: [f64; 3]) -> Composite {
    let mut c = DVector::zeros(13);
    c.fixed_rows_mut::<3>(0).copy_from(&Vector3::from(p));
    c.fixed_rows_mut::<3>(3).copy_from(&Vector3::from(v));
    put_quaternion(&mut c, 6, rotation);
    c.fixed_rows_mut::<3>(10).copy_from(&Vector3::from(w));
    Composite::new(QUATERNION_LAYOUT, c).unwrap()
}

fn quaternion_pose_velocity(x: &Composite) -> PoseVelocity {
    PoseVelocity {
        camera_from_object: Isometry3::from_parts(Translation3::from(x.vector3_at(0)), x.quaternion_at(6)),
        linear_velocity_mps: x.vector3_at(3),
        angular_velocity_radps: x.vector3_at(10),
    }
}

fn euler_pose_velocity(x: &Composite) -> PoseVelocity {
    let o = x.vector3_at(6);
    PoseVelocity {
        camera_from_object: Isometry3::from_parts(
            Translation3::from(x.vector3_at(0)),
            UnitQuaternion::from_rotation_matrix(&euler::rotation_from_zyx(&o)),
        ),
        linear_velocity_mps: x.vector3_at(3),
        angular_velocity_radps: euler::angular_velocity_from_rates_matrix(&o) * x.vector3_at(9),
    }
}

fn diagonal(values: &[f64]) -> DMatrix<f64> {
    DMatrix::from_diagonal(&DVector::from_column_slice(values))
}

fn block(m: &Matrix6<f64>, r: usize, c: usize) -> Matrix3<f64> {
    m.fixed_view::<3, 3>(r, c).into_owned()
}

const VARIANCES: [f64; 12] = [1e-6, 2e-6, 3e-6, 4e-4, 5e-4, 6e-4, 1e-3, 2e-3, 3e-3, 4e-2, 5e-2, 6e-2];

/// At rest, a quaternion state's blocks pass through: position and the
/// rotation vector (the left `⊕` is already about the camera's axes), and the
/// velocities turned into the object frame, `Rᵀ Σ R`. Catches a twist left in
/// the camera frame, `R Σ Rᵀ` instead of `Rᵀ Σ R`, or a right-hand rotation error.
#[test]
fn at_rest_the_blocks_of_a_quaternion_belief_pass_through_turned_into_the_object_frame() {
    let rotation = UnitQuaternion::from_euler_angles(0.3, -0.5, 1.1);
    let mean = quaternion_state([0.1, -0.2, 0.6], [0.0; 3], &rotation, [0.0; 3]);
    let cov = diagonal(&VARIANCES);
    let out = odometry_covariance(&mean, &cov, quaternion_pose_velocity).unwrap();
    let d =
        |k: usize| Matrix3::from_diagonal(&Vector3::new(VARIANCES[k], VARIANCES[k + 1], VARIANCES[k + 2]));
    let r = rotation.to_rotation_matrix().into_inner();
    assert_relative_eq!(block(&out.pose, 0, 0), d(0), epsilon = 1e-12);
    assert_relative_eq!(block(&out.pose, 3, 3), d(6), epsilon = 1e-10);
    assert_relative_eq!(block(&out.pose, 0, 3), Matrix3::zeros(), epsilon = 1e-12);
    assert_relative_eq!(block(&out.twist_in_child, 0, 0), r.transpose() * d(3) * r, epsilon = 1e-10);
    assert_relative_eq!(block(&out.twist_in_child, 3, 3), r.transpose() * d(9) * r, epsilon = 1e-9);
    assert_relative_eq!(block(&out.twist_in_child, 0, 3), Matrix3::zeros(), epsilon = 1e-12);
}

/// Euler angles: the rotation error about the camera's axes is `E(o) δo`
/// (4.2), and the angular velocity `E(o) ȯ` turned into the object frame.
/// Catches the Euler angles' covariance passed on as if it were about fixed
/// axes (it is not, away from `o = 0`).
#[test]
fn euler_angle_errors_become_rotations_about_the_camera_axes_through_e_of_o() {
    let o = Vector3::new(0.4, -0.7, 1.2);
    let mut c = DVector::zeros(12);
    c.fixed_rows_mut::<3>(0).copy_from(&Vector3::new(0.0, 0.1, 0.5));
    c.fixed_rows_mut::<3>(6).copy_from(&o);
    let mean = Composite::new(EULER_LAYOUT, c).unwrap();
    let cov = diagonal(&VARIANCES);
    let out = odometry_covariance(&mean, &cov, euler_pose_velocity).unwrap();
    let e = euler::angular_velocity_from_rates_matrix(&o);
    let r = euler::rotation_from_zyx(&o).into_inner();
    let d =
        |k: usize| Matrix3::from_diagonal(&Vector3::new(VARIANCES[k], VARIANCES[k + 1], VARIANCES[k + 2]));
    assert_relative_eq!(block(&out.pose, 3, 3), e * d(6) * e.transpose(), epsilon = 1e-9);
    assert_relative_eq!(
        block(&out.twist_in_child, 3, 3),
        r.transpose() * e * d(9) * e.transpose() * r,
        epsilon = 1e-8
    );
}

/// Moving and turning, with every state correlated: the linearised
/// covariance agrees with the spread of states sampled from the belief and
/// mapped exactly (small covariance, so first order is accurate). Catches a
/// Jacobian missing the orientation's effect on the object-frame twist, or a
/// transposed one.
#[test]
fn the_linearised_covariance_agrees_with_sampled_states() {
    let rotation = UnitQuaternion::from_euler_angles(-0.8, 0.2, 2.0);
    let mean = quaternion_state([0.1, 0.0, 0.7], [0.3, -0.2, 0.1], &rotation, [1.5, -0.5, 2.0]);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
    let a = DMatrix::<f64>::from_fn(12, 12, |_, _| StandardNormal.sample(&mut rng));
    let cov = (&a * a.transpose()) * 1e-4 + diagonal(&VARIANCES) * 0.01;
    let out = odometry_covariance(&mean, &cov, quaternion_pose_velocity).unwrap();
    let l = cov.clone().cholesky().unwrap().l();
    let reference = quaternion_pose_velocity(&mean);
    let samples = 40_000;
    let mut ys = Vec::with_capacity(samples);
    for _ in 0..samples {
        let z = DVector::<f64>::from_fn(12, |_, _| StandardNormal.sample(&mut rng));
        let x = mean.oplus((&l * z).as_slice());
        let e = quaternion_pose_velocity(&x);
        let dtheta =
            quaternion::ominus(&e.camera_from_object.rotation, &reference.camera_from_object.rotation);
        let mut y = DVector::zeros(12);
        y.fixed_rows_mut::<3>(0).copy_from(&e.camera_from_object.translation.vector);
        y.fixed_rows_mut::<3>(3).copy_from(&dtheta);
        y.fixed_rows_mut::<6>(6).copy_from(&twist_in_object(&e));
        ys.push(y);
    }
    let mean_y = ys.iter().fold(DVector::zeros(12), |s, y| s + y) / samples as f64;
    let sampled =
        ys.iter().fold(DMatrix::zeros(12, 12), |s, y| s + (y - &mean_y) * (y - &mean_y).transpose())
            / samples as f64;
    for (offset, linear) in [(0, &out.pose), (6, &out.twist_in_child)] {
        for r in 0..6 {
            for c in 0..6 {
                let scale = (linear[(r, r)] * linear[(c, c)]).sqrt();
                let s = sampled[(offset + r, offset + c)];
                assert!(
                    (s - linear[(r, c)]).abs() < 0.05 * scale,
                    "({offset}+{r}, {c}): sampled {s}, linear {}",
                    linear[(r, c)]
                );
            }
        }
    }
}

#[test]
fn a_covariance_of_the_wrong_size_is_an_error() {
    let mean = quaternion_state([0.0; 3], [0.0; 3], &UnitQuaternion::identity(), [0.0; 3]);
    let err = odometry_covariance(&mean, &DMatrix::identity(6, 6), quaternion_pose_velocity).unwrap_err();
    assert!(matches!(err, crate::EstimatorError::DimensionMismatch { expected: 12, got: 6, .. }), "{err}");
}

#[test]
fn row_major_reads_rows_first() {
    let m = Matrix6::from_fn(|r, c| (10 * r + c) as f64);
    let v = OdometryCovariance::row_major(&m);
    assert_eq!(&v[..3], &[0.0, 1.0, 2.0]);
    assert_eq!(v[6], 10.0);
    assert_eq!(v.len(), 36);
}
