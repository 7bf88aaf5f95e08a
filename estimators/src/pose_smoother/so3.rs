//! The SO(3) pieces the error-state filter needs beyond the crate's
//! quaternion operators ([`crate::orientation::quaternion`]: `exp`, `log`,
//! `⊕`, `⊖`): the skew matrix and the left Jacobian.

use nalgebra::{Matrix3, Vector3};

/// Below this angle (rad) the left Jacobian uses its series.
const SMALL_ANGLE_RAD: f64 = 1e-6;

/// `[a]x`: the matrix with `[a]x b = a x b`.
#[rustfmt::skip]
pub(super) fn skew(a: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(
        0.0,  -a.z,  a.y,
        a.z,   0.0, -a.x,
        -a.y,  a.x,  0.0,
    )
}

/// The left Jacobian of SO(3) at the rotation vector `phi` (rad) (Solà et
/// al., *A micro Lie theory for state estimation in robotics*, 2018, App.
/// B): `Exp(phi + d) ≈ Exp(J_l(phi) d) Exp(phi)` for a small `d`.
/// `J_l = I + (1 - cos a)/a^2 [phi]x + (a - sin a)/a^3 [phi]x^2`, `a = |phi|`;
/// its series `I + [phi]x/2 + [phi]x^2/6` below 1e-6 rad.
pub(super) fn left_jacobian(phi: &Vector3<f64>) -> Matrix3<f64> {
    let a = phi.norm();
    let K = skew(phi);
    let (c1, c2) = if a < SMALL_ANGLE_RAD {
        (0.5, 1.0 / 6.0)
    } else {
        ((1.0 - a.cos()) / (a * a), (a - a.sin()) / (a * a * a))
    };
    Matrix3::identity() + K * c1 + K * K * c2
}

#[cfg(test)]
mod tests {
    use approx::assert_relative_eq;

    use super::*;
    use crate::orientation::quaternion::{exp, log};

    #[test]
    fn the_left_jacobian_moves_a_small_step_to_the_left() {
        for phi in [Vector3::new(0.3, -1.2, 0.7), Vector3::new(1e-8, 0.0, 2e-8), Vector3::new(0.0, 2.9, 0.1)]
        {
            let d = Vector3::new(1e-6, -2e-6, 1.5e-6);
            // Exp(phi + d) Exp(phi)^-1 = Exp(J_l d) to second order in d.
            let left = log(&(exp(&(phi + d)) * exp(&phi).inverse()));
            assert_relative_eq!(left, left_jacobian(&phi) * d, epsilon = 1e-11);
        }
        assert_relative_eq!(
            skew(&Vector3::new(1.0, 2.0, 3.0)) * Vector3::new(-1.0, 0.5, 2.0),
            Vector3::new(1.0, 2.0, 3.0).cross(&Vector3::new(-1.0, 0.5, 2.0))
        );
    }
}
