//! The MaskUKF measurement function (thesis Sec. 4.1.4, (4.8)-(4.11)):
//! for a state `x`, each measured point `z_j` is predicted by its projection
//! `π_j(x)` on the object in configuration `x` (4.9), approximated by the
//! nearest model point: `z_j` is moved to the object frame of `x`, the k-d
//! tree finds the nearest `A_k`, and `A_k` goes back to the camera frame.

#![expect(non_snake_case, reason = "matrices are named as in the thesis's equations (F, H, Q, R, P, K)")]

use nalgebra::{DMatrix, Isometry3, Matrix3, Point3, Vector3};

use super::model::ObjectPoints;
use super::state::camera_from_object;
use crate::orientation::Composite;

/// `h_t(X_i)` for every sigma point `X_i`: the `3L x (2n+1)` matrix whose
/// column `i` stacks `π_1(X_i), ..., π_L(X_i)` (4.11). The loop runs over the
/// points outside and the sigma points inside: one measured point seen from
/// the sigma points gives queries close together, which
/// [`ObjectPoints::nearest_cluster`] answers exactly with one k-NN query.
pub fn predicted_clouds(
    sigma_points: &[Composite],
    points_in_camera: &[Point3<f64>],
    model: &ObjectPoints,
) -> DMatrix<f64> {
    let poses: Vec<(Matrix3<f64>, Vector3<f64>)> = sigma_points
        .iter()
        .map(|x| {
            let t = camera_from_object(x);
            (t.rotation.to_rotation_matrix().into_inner(), t.translation.vector)
        })
        .collect();
    let mut Z = DMatrix::<f64>::zeros(3 * points_in_camera.len(), sigma_points.len());
    let mut queries = Vec::with_capacity(poses.len());
    let mut nearest = Vec::with_capacity(poses.len());
    for (j, z) in points_in_camera.iter().enumerate() {
        // object_from_camera * z = R^T (z - t), for every sigma point.
        queries.clear();
        queries.extend(
            poses
                .iter()
                .map(|(rotation, translation)| Point3::from(rotation.tr_mul(&(z.coords - translation)))),
        );
        model.nearest_cluster(&queries, &mut nearest);
        for (i, ((rotation, translation), a)) in poses.iter().zip(&nearest).enumerate() {
            let pi = rotation * model.points()[*a].coords + translation;
            Z[(3 * j, i)] = pi.x;
            Z[(3 * j + 1, i)] = pi.y;
            Z[(3 * j + 2, i)] = pi.z;
        }
    }
    Z
}

/// The projections `π_j` of `points_in_camera` on the object at pose
/// `camera_from_object` (4.9), camera frame (m).
pub fn project(
    points_in_camera: &[Point3<f64>],
    camera_from_object: &Isometry3<f64>,
    model: &ObjectPoints,
) -> Vec<Point3<f64>> {
    let object_from_camera = camera_from_object.inverse();
    points_in_camera.iter().map(|z| camera_from_object * model.nearest(&(object_from_camera * z))).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::maskukf::state::{LAYOUT, state_from_pose};
    use crate::orientation::PoseVelocity;
    use nalgebra::{Translation3, UnitQuaternion};

    #[test]
    fn points_on_the_model_project_onto_themselves() {
        let model_points: Vec<Point3<f64>> =
            (0..100).map(|i| Point3::new((i % 10) as f64 * 0.01, (i / 10) as f64 * 0.01, 0.0)).collect();
        let model = ObjectPoints::new(model_points.clone()).unwrap();
        let pose = Isometry3::from_parts(
            Translation3::new(0.05, -0.02, 0.7),
            UnitQuaternion::from_euler_angles(0.3, -0.2, 0.9),
        );
        let measured: Vec<Point3<f64>> = model_points.iter().step_by(7).map(|a| pose * a).collect();
        let x = state_from_pose(&PoseVelocity::at_rest(pose));
        assert_eq!(x.layout(), LAYOUT);
        let Z = predicted_clouds(&[x], &measured, &model);
        for (j, z) in measured.iter().enumerate() {
            assert!(
                (Vector3::new(Z[(3 * j, 0)], Z[(3 * j + 1, 0)], Z[(3 * j + 2, 0)]) - z.coords).norm() < 1e-6
            );
        }
        let pi = project(&measured, &pose, &model);
        assert!(pi.iter().zip(&measured).all(|(a, b)| (a - b).norm() < 1e-6));
    }
}
