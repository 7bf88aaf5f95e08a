//! Unit-quaternion operators for Kalman filtering (thesis Sec. 2.3.2,
//! Algorithm 9): exponential and logarithm maps between the Lie algebra
//! (rotation vectors in R^3) and unit quaternions (2.112)-(2.113), the "sum"
//! `q ⊕ ω` (2.114), the "difference" `q1 ⊖ q2` (2.115) and the weighted mean
//! as the dominant eigenvector of `Σ λ_i q_i q_i^T` (2.116).
//!
//! Quaternions are nalgebra's [`UnitQuaternion`]. Rotation vectors are in
//! radians, expressed in the fixed (left) frame: `q ⊕ ω = exp(ω) q`, so `ω`
//! is a perturbation of `q` seen from the frame `q` maps into.

use nalgebra::{Matrix4, Quaternion, SymmetricEigen, UnitQuaternion, Vector3, Vector4};

/// Below this norm a rotation vector (rad) or a vector part is treated as zero
/// and the first-order series is used instead of the closed forms.
const SMALL: f64 = 1e-12;

/// `exp(ω)` (2.112): the unit quaternion rotating by `|ω|` rad about `ω/|ω|`;
/// the identity for `ω = 0`.
pub fn exp(omega: &Vector3<f64>) -> UnitQuaternion<f64> {
    let angle = omega.norm();
    if angle < SMALL {
        // First order: (1, ω/2), renormalised.
        return UnitQuaternion::new_normalize(Quaternion::new(
            1.0,
            omega.x / 2.0,
            omega.y / 2.0,
            omega.z / 2.0,
        ));
    }
    let (s, c) = (angle / 2.0).sin_cos();
    let axis = omega / angle;
    UnitQuaternion::new_unchecked(Quaternion::new(c, axis.x * s, axis.y * s, axis.z * s))
}

/// `log(q)` (2.113): the rotation vector `ω` (rad) with `exp(ω) = q`, of norm
/// at most π. The scalar part is made non-negative first (double cover), so
/// `log(q) = log(-q)`.
pub fn log(q: &UnitQuaternion<f64>) -> Vector3<f64> {
    let q = q.quaternion();
    let (w, v) = if q.w < 0.0 { (-q.w, -q.imag()) } else { (q.w, q.imag()) };
    let norm_v = v.norm();
    if norm_v < SMALL {
        return 2.0 * v;
    }
    2.0 * v * (norm_v.atan2(w) / norm_v)
}

/// `q ⊕ ω := exp(ω) q` (2.114).
pub fn oplus(q: &UnitQuaternion<f64>, omega: &Vector3<f64>) -> UnitQuaternion<f64> {
    exp(omega) * q
}

/// `q1 ⊖ q2 := log(q1 q2^-1)` (2.115): the rotation vector taking `q2` to `q1`.
pub fn ominus(q1: &UnitQuaternion<f64>, q2: &UnitQuaternion<f64>) -> Vector3<f64> {
    log(&(q1 * q2.inverse()))
}

/// The weighted mean `q̄({q_i}, {λ_i})` (2.116): the unit eigenvector of the
/// largest eigenvalue of `M = Σ λ_i q_i q_i^T` (4x4, quaternions as 4-vectors).
/// It does not depend on the signs of the `q_i` (double cover). The result is
/// returned with a non-negative scalar part.
///
/// Returns `None` when there is nothing to average, the lengths differ, or
/// `M` holds non-finite values.
pub fn weighted_mean(quaternions: &[UnitQuaternion<f64>], weights: &[f64]) -> Option<UnitQuaternion<f64>> {
    if quaternions.is_empty() || quaternions.len() != weights.len() {
        return None;
    }
    let mut m = Matrix4::<f64>::zeros();
    for (q, &lambda) in quaternions.iter().zip(weights) {
        let v: Vector4<f64> = q.quaternion().coords;
        m += lambda * v * v.transpose();
    }
    dominant_eigenvector(&m)
}

/// The unit eigenvector of the largest eigenvalue of the symmetric `m`, as a
/// quaternion with non-negative scalar part.
fn dominant_eigenvector(m: &Matrix4<f64>) -> Option<UnitQuaternion<f64>> {
    if !m.iter().all(|v| v.is_finite()) {
        return None;
    }
    let eigen = SymmetricEigen::new(*m);
    let (best, _) = eigen.eigenvalues.iter().enumerate().max_by(|a, b| a.1.total_cmp(b.1))?;
    let v: Vector4<f64> = eigen.eigenvectors.column(best).into_owned();
    let norm = v.norm();
    if !(norm.is_finite() && norm > 0.0) {
        return None;
    }
    let sign = if v[3] < 0.0 { -1.0 } else { 1.0 };
    // nalgebra stores quaternion coordinates as (i, j, k, w).
    Some(UnitQuaternion::new_unchecked(Quaternion::from(v * (sign / norm))))
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;
    use std::f64::consts::PI;

    fn q(axis: [f64; 3], angle: f64) -> UnitQuaternion<f64> {
        UnitQuaternion::from_scaled_axis(Vector3::from(axis).normalize() * angle)
    }

    #[test]
    fn exp_and_log_are_inverse_and_match_nalgebra() {
        for omega in [
            Vector3::new(0.3, -0.2, 0.9),
            Vector3::new(1e-14, 0.0, 0.0),
            Vector3::new(0.0, 0.0, 0.0),
            Vector3::new(0.0, 3.0, 0.1),
        ] {
            let qe = exp(&omega);
            let reference = UnitQuaternion::from_scaled_axis(omega);
            assert_relative_eq!(qe.angle_to(&reference), 0.0, epsilon = 1e-12);
            assert_relative_eq!(log(&qe), omega, epsilon = 1e-12);
        }
    }

    #[test]
    fn log_takes_the_short_way_round_the_double_cover() {
        let a = q([0.0, 0.0, 1.0], 0.7);
        let negated = UnitQuaternion::new_unchecked(-a.into_inner());
        assert_relative_eq!(log(&negated), log(&a), epsilon = 1e-12);
        // A rotation of 3π/2 about z is -π/2 about z.
        assert_relative_eq!(
            log(&q([0.0, 0.0, 1.0], 1.5 * PI)),
            Vector3::new(0.0, 0.0, -PI / 2.0),
            epsilon = 1e-12
        );
    }

    #[test]
    fn oplus_and_ominus_are_inverse() {
        let q1 = q([1.0, 2.0, 3.0], 0.4);
        let omega = Vector3::new(-0.1, 0.25, 0.05);
        let q2 = oplus(&q1, &omega);
        assert_relative_eq!(ominus(&q2, &q1), omega, epsilon = 1e-12);
        assert_relative_eq!(oplus(&q1, &ominus(&q2, &q1)).angle_to(&q2), 0.0, epsilon = 1e-12);
    }

    #[test]
    fn the_mean_of_symmetric_perturbations_is_the_centre() {
        let centre = q([0.2, -1.0, 0.4], 1.1);
        let deltas = [0.2, -0.2]
            .iter()
            .flat_map(|&s| [Vector3::new(s, 0.0, 0.0), Vector3::new(0.0, s, 0.0), Vector3::new(0.0, 0.0, s)]);
        let mut qs = vec![centre];
        qs.extend(deltas.map(|d| oplus(&centre, &d)));
        // Flip some signs: the mean must not care.
        qs[2] = UnitQuaternion::new_unchecked(-qs[2].into_inner());
        qs[5] = UnitQuaternion::new_unchecked(-qs[5].into_inner());
        let weights = [0.4, 0.1, 0.1, 0.1, 0.1, 0.1, 0.1];
        let mean = weighted_mean(&qs, &weights).unwrap();
        assert_relative_eq!(mean.angle_to(&centre), 0.0, epsilon = 1e-12);
    }

    /// The eigenvector solution maximises `Σ λ_i (q_i · q̄)^2` over unit q̄, and
    /// power iteration on `M` (an independent method) finds the same vector.
    #[test]
    fn the_mean_is_the_eigenvector_solution() {
        let qs: Vec<UnitQuaternion<f64>> = (0..9)
            .map(|i| {
                let t = i as f64;
                q([1.0 + t.sin(), 0.5 * t.cos(), 0.3], 0.8 + 0.15 * (1.3 * t).sin())
            })
            .collect();
        let weights: Vec<f64> = (0..9).map(|i| 0.05 + 0.02 * i as f64).collect();
        let mean = weighted_mean(&qs, &weights).unwrap();
        let objective = |m: &UnitQuaternion<f64>| -> f64 {
            qs.iter().zip(&weights).map(|(q, w)| w * q.coords.dot(&m.coords).powi(2)).sum()
        };
        let best = objective(&mean);
        for i in 0..200 {
            let t = i as f64 * 0.37;
            let other = oplus(&mean, &(Vector3::new(t.sin(), (2.0 * t).cos(), (0.5 * t).sin()) * 0.05));
            assert!(objective(&other) <= best + 1e-15);
        }
        // Power iteration on M, shifted to be positive definite.
        let mut m = Matrix4::<f64>::zeros();
        for (q, w) in qs.iter().zip(&weights) {
            m += *w * q.coords * q.coords.transpose();
        }
        let mut v = Vector4::new(0.1, 0.2, 0.3, 0.9).normalize();
        for _ in 0..2000 {
            v = (m * v).normalize();
        }
        if v[3] < 0.0 {
            v = -v;
        }
        assert_relative_eq!(v, mean.coords, epsilon = 1e-9);
    }

    #[test]
    fn an_empty_or_ragged_mean_is_none() {
        assert!(weighted_mean(&[], &[]).is_none());
        assert!(weighted_mean(&[UnitQuaternion::identity()], &[0.5, 0.5]).is_none());
        assert!(weighted_mean(&[UnitQuaternion::identity()], &[f64::NAN]).is_none());
    }
}
