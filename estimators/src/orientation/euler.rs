//! Euler-angle operators for Kalman filtering (thesis Sec. 2.3.1, Algorithm 8):
//! angles are summed, subtracted and averaged on the unit circle, (2.94)-(2.98),
//! component by component. Also the ZYX (roll-pitch-yaw) parametrisation
//! `R = Rz(φ) Ry(χ) Rx(ψ)` (2.92) and the map from Euler rates to the angular
//! velocity (4.2). Angles in radians.

use nalgebra::{Matrix3, Rotation3, Vector3};

/// `α ⊕ β := arg(exp(j(α + β)))` (2.94): the sum wrapped to `(-π, π]`.
pub fn oplus(alpha: f64, beta: f64) -> f64 {
    wrap(alpha + beta)
}

/// `α ⊖ β := α ⊕ (-β)` (2.96): the difference wrapped to `(-π, π]`.
pub fn ominus(alpha: f64, beta: f64) -> f64 {
    wrap(alpha - beta)
}

/// `arg(exp(jα))`: `α` wrapped to `(-π, π]`.
pub fn wrap(alpha: f64) -> f64 {
    let (s, c) = alpha.sin_cos();
    s.atan2(c)
}

/// The circular mean `arg(Σ λ_i exp(j α_i))` (2.98). `None` when the weighted
/// directions cancel out (no defined mean), the inputs are empty, or their
/// lengths differ.
pub fn circular_mean(angles: &[f64], weights: &[f64]) -> Option<f64> {
    if angles.is_empty() || angles.len() != weights.len() {
        return None;
    }
    let (mut s, mut c, mut total) = (0.0, 0.0, 0.0);
    for (&a, &w) in angles.iter().zip(weights) {
        let (sa, ca) = a.sin_cos();
        s += w * sa;
        c += w * ca;
        total += w.abs();
    }
    let norm = s.hypot(c);
    (norm.is_finite() && norm > 1e-12 * total).then(|| s.atan2(c))
}

/// ZYX Euler angles `o = (φ, χ, ψ)` of the rotation `R = Rz(φ) Ry(χ) Rx(ψ)`
/// (2.92): `φ` about z, `χ` about y, `ψ` about x, all rad.
pub fn zyx_from_rotation(rotation: &Rotation3<f64>) -> Vector3<f64> {
    // nalgebra's euler_angles are (roll about x, pitch about y, yaw about z)
    // of R = Rz(yaw) Ry(pitch) Rx(roll).
    let (roll, pitch, yaw) = rotation.euler_angles();
    Vector3::new(yaw, pitch, roll)
}

/// The rotation `R = Rz(φ) Ry(χ) Rx(ψ)` of the ZYX angles `o = (φ, χ, ψ)` (2.92).
pub fn rotation_from_zyx(o: &Vector3<f64>) -> Rotation3<f64> {
    Rotation3::from_euler_angles(o[2], o[1], o[0])
}

/// The matrix of (4.2) mapping the ZYX Euler rates `ȯ` (rad/s) to the angular
/// velocity `ω` (rad/s) in the fixed frame: `ω = E(o) ȯ`. Singular at `cos χ = 0`.
#[rustfmt::skip]
pub fn angular_velocity_from_rates_matrix(o: &Vector3<f64>) -> Matrix3<f64> {
    let (s_phi, c_phi) = o[0].sin_cos();
    let (s_chi, c_chi) = o[1].sin_cos();
    Matrix3::new(
        0.0, -s_phi, c_phi * c_chi,
        0.0,  c_phi, s_phi * c_chi,
        1.0,  0.0,   -s_chi,
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;
    use std::f64::consts::PI;

    #[test]
    fn sums_and_differences_stay_on_the_circle() {
        // The thesis's example: 2π and -2π are the same angle.
        assert_relative_eq!(ominus(2.0 * PI, -2.0 * PI), 0.0, epsilon = 1e-12);
        assert_relative_eq!(oplus(3.0, 0.5), 3.5 - 2.0 * PI, epsilon = 1e-12);
        assert_relative_eq!(ominus(-3.0, 3.0), 2.0 * PI - 6.0, epsilon = 1e-12);
    }

    #[test]
    fn the_circular_mean_across_the_cut_is_pi() {
        let mean = circular_mean(&[PI - 0.1, -PI + 0.1], &[0.5, 0.5]).unwrap();
        assert_relative_eq!(mean.abs(), PI, epsilon = 1e-12);
        let mean = circular_mean(&[0.2, 0.4, 0.3], &[0.25, 0.25, 0.5]).unwrap();
        assert_relative_eq!(mean, 0.3, epsilon = 1e-3);
        assert!(circular_mean(&[0.0, PI], &[0.5, 0.5]).is_none());
    }

    #[test]
    fn zyx_round_trips_and_composes_as_documented() {
        let o = Vector3::new(0.4, -0.3, 1.2);
        let r = rotation_from_zyx(&o);
        let manual = Rotation3::from_axis_angle(&Vector3::z_axis(), o[0])
            * Rotation3::from_axis_angle(&Vector3::y_axis(), o[1])
            * Rotation3::from_axis_angle(&Vector3::x_axis(), o[2]);
        assert_relative_eq!(r.matrix(), manual.matrix(), epsilon = 1e-12);
        assert_relative_eq!(zyx_from_rotation(&r), o, epsilon = 1e-12);
    }

    /// `ω^ = Ṙ R^T` with Ṙ by central differences along a path of Euler angles.
    #[test]
    fn the_rate_matrix_gives_the_angular_velocity() {
        let o = Vector3::new(0.7, 0.2, -0.5);
        let o_dot = Vector3::new(0.3, -1.1, 0.8);
        let h = 1e-6;
        let r_plus = rotation_from_zyx(&(o + o_dot * h));
        let r_minus = rotation_from_zyx(&(o - o_dot * h));
        let r_dot = (r_plus.matrix() - r_minus.matrix()) / (2.0 * h);
        let w_hat = r_dot * rotation_from_zyx(&o).matrix().transpose();
        let omega = Vector3::new(w_hat[(2, 1)], w_hat[(0, 2)], w_hat[(1, 0)]);
        assert_relative_eq!(angular_velocity_from_rates_matrix(&o) * o_dot, omega, epsilon = 1e-8);
    }
}
