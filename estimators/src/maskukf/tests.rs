//! MaskUKF on synthetic clouds of a box seen from the camera.

use std::sync::Arc;

use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};

use super::*;
use crate::metrics::{perturbed_start, position_error_m, rotation_error_deg};

const HALF: [f64; 3] = [0.05, 0.03, 0.08];

/// Points on the surface of a 10 x 6 x 16 cm box, with outward normals.
fn box_surface(step: f64) -> Vec<(Point3<f64>, Vector3<f64>)> {
    let mut out = Vec::new();
    for axis in 0..3 {
        let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
        for sign in [-1.0, 1.0] {
            let nu = (2.0 * HALF[u] / step).round() as i32;
            let nv = (2.0 * HALF[v] / step).round() as i32;
            for i in 0..=nu {
                for j in 0..=nv {
                    let mut p = [0.0; 3];
                    p[axis] = sign * HALF[axis];
                    p[u] = -HALF[u] + i as f64 * step;
                    p[v] = -HALF[v] + j as f64 * step;
                    let mut n = Vector3::zeros();
                    n[axis] = sign;
                    out.push((Point3::from(p), n));
                }
            }
        }
    }
    out
}

fn model() -> Arc<ObjectPoints> {
    Arc::new(ObjectPoints::new(box_surface(0.005).into_iter().map(|(p, _)| p).collect()).unwrap())
}

/// The visible part of the box at `pose` as the camera (origin) sees it, with
/// deterministic noise of about `noise_m` per coordinate.
fn visible_cloud(pose: &Isometry3<f64>, noise_m: f64, seed: u64) -> Vec<Point3<f64>> {
    let mut rng = seed;
    box_surface(0.004)
        .into_iter()
        .filter_map(|(p, n)| {
            let p_c = pose * p;
            let n_c = pose.rotation * n;
            (n_c.dot(&(-p_c.coords)) > 0.0).then(|| {
                let mut jitter = || {
                    rng = splitmix64(rng);
                    ((rng >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 2.0 * noise_m * 3f64.sqrt()
                };
                p_c + Vector3::new(jitter(), jitter(), jitter())
            })
        })
        .collect()
}

fn true_pose(t: f64) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(0.05 + 0.1 * t, -0.02, 0.7),
        UnitQuaternion::from_euler_angles(0.4, 0.3 + 0.5 * t, 0.2),
    )
}

#[test]
fn converges_from_a_perturbed_start_on_a_moving_box() {
    let dt = 1.0 / 30.0;
    let start = perturbed_start(&true_pose(0.0));
    let mut f = MaskUkf::new(model(), MaskUkfConfig::default(), &PoseVelocity::at_rest(start)).unwrap();
    for k in 1..=60 {
        let truth = true_pose(k as f64 * dt);
        let cloud = visible_cloud(&truth, 0.002, k);
        let report =
            f.step(dt, CloudInput::Cloud { points_in_camera: &cloud, mask_pixels: cloud.len() }).unwrap();
        assert_eq!(report.used, MeasurementUsed::Measured, "frame {k}");
    }
    let truth = true_pose(60.0 * dt);
    let e = f.estimate();
    assert!(
        position_error_m(&e.camera_from_object, &truth) < 0.01,
        "{}",
        position_error_m(&e.camera_from_object, &truth)
    );
    assert!(rotation_error_deg(&e.camera_from_object, &truth) < 5.0);
    // The linear velocity (0.1, 0, 0) m/s is tracked.
    assert!(
        (e.linear_velocity_mps - Vector3::new(0.1, 0.0, 0.0)).norm() < 0.05,
        "{:?}",
        e.linear_velocity_mps
    );
}

#[test]
fn outliers_are_removed_before_the_correction() {
    let truth = true_pose(0.0);
    let mut cloud = visible_cloud(&truth, 0.001, 3);
    let n = cloud.len();
    // 10% of the points 10-20 cm behind the object (background seen through the mask).
    for (i, p) in cloud.iter_mut().enumerate().filter(|(i, _)| i % 10 == 0) {
        *p += p.coords.normalize() * (0.1 + 0.01 * (i % 10) as f64);
    }
    let config = MaskUkfConfig { max_points: 10_000, ..MaskUkfConfig::default() };
    let mut f = MaskUkf::new(model(), config.clone(), &PoseVelocity::at_rest(truth)).unwrap();
    let report = f.step(1.0 / 30.0, CloudInput::Cloud { points_in_camera: &cloud, mask_pixels: n }).unwrap();
    // The pairwise test of (4.12) misses an outlier whose displacement is
    // about perpendicular to the line to its furthest point; most are caught.
    assert!(report.outliers >= n / 20, "{} of {}", report.outliers, n / 10);
    let with = position_error_m(&f.estimate().camera_from_object, &truth);
    let mut g = MaskUkf::new(
        model(),
        MaskUkfConfig { outlier_rejection: false, ..config },
        &PoseVelocity::at_rest(truth),
    )
    .unwrap();
    g.step(1.0 / 30.0, CloudInput::Cloud { points_in_camera: &cloud, mask_pixels: n }).unwrap();
    let without = position_error_m(&g.estimate().camera_from_object, &truth);
    assert!(with < 0.5 * without, "with {with} without {without}");
}

#[test]
fn missing_measurements_use_the_virtual_cloud_and_stop_the_object() {
    let truth = true_pose(0.0);
    let moving = PoseVelocity {
        camera_from_object: truth,
        linear_velocity_mps: Vector3::new(0.3, 0.0, 0.0),
        angular_velocity_radps: Vector3::new(0.0, 1.0, 0.0),
    };
    let mut f = MaskUkf::new(model(), MaskUkfConfig::default(), &moving).unwrap();
    let report = f.step(1.0 / 30.0, CloudInput::Missing).unwrap();
    assert_eq!(report.used, MeasurementUsed::VirtualNoMask);
    for _ in 0..30 {
        f.step(1.0 / 30.0, CloudInput::Cloud { points_in_camera: &[], mask_pixels: 0 }).unwrap();
    }
    let e = f.estimate();
    assert!(e.linear_velocity_mps.norm() < 0.05, "{:?}", e.linear_velocity_mps);
    // Rotation is less constrained by the cloud (R has σ ≈ 3 cm): ω decays slower.
    assert!(e.angular_velocity_radps.norm() < 0.5, "{:?}", e.angular_velocity_radps);
    assert!(position_error_m(&e.camera_from_object, &truth) < 0.05);
    // A mask whose depth is mostly invalid counts as missing too.
    let cloud = visible_cloud(&truth, 0.001, 1);
    let report = f
        .step(1.0 / 30.0, CloudInput::Cloud { points_in_camera: &cloud, mask_pixels: cloud.len() * 10 })
        .unwrap();
    assert_eq!(report.used, MeasurementUsed::VirtualLowValidRatio);
}

#[test]
fn bad_input_never_puts_nan_in_the_state() {
    let truth = true_pose(0.0);
    let mut f = MaskUkf::new(model(), MaskUkfConfig::default(), &PoseVelocity::at_rest(truth)).unwrap();
    assert!(matches!(f.step(0.0, CloudInput::Missing), Err(MaskUkfError::BadTimeStep { .. })));
    assert!(matches!(f.step(f64::NAN, CloudInput::Missing), Err(MaskUkfError::BadTimeStep { .. })));
    let nan_cloud = vec![Point3::new(f64::NAN, 0.0, 0.7); 50];
    let report =
        f.step(1.0 / 30.0, CloudInput::Cloud { points_in_camera: &nan_cloud, mask_pixels: 50 }).unwrap();
    assert_eq!(report.used, MeasurementUsed::VirtualLowValidRatio);
    assert!(f.estimate().is_finite());
    assert!(f.belief().cov.iter().all(|v| v.is_finite()));
    let bad = PoseVelocity {
        linear_velocity_mps: Vector3::new(f64::NAN, 0.0, 0.0),
        ..PoseVelocity::at_rest(truth)
    };
    assert!(matches!(
        MaskUkf::new(model(), MaskUkfConfig::default(), &bad),
        Err(MaskUkfError::BadInitialState)
    ));
}
