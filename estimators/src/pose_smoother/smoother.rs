//! The backward pass: the RTS smoother (thesis Algorithm 10, eq. 2.143) on
//! the translation, and its extended form on the orientation's manifold
//! (the correction computed in the tangent space of the prediction, retracted
//! at the filtered estimate; see the module documentation of [`super`]).
#![expect(non_snake_case, reason = "matrices are named as in the thesis's equations (F, P, G)")]

use nalgebra::{SMatrix, Vector3, Vector6};

use super::filter::{Belief, Step, symmetric};
use crate::EstimatorError;
use crate::orientation::quaternion::{exp, ominus};

/// `p(x_k | z_1:T)` for every step of a forward pass (the steps from the
/// first measured sample, index `first`, on), from the last step backwards.
/// Fails when a prior covariance is singular, naming the sample.
pub(super) fn smooth(steps: &[Step], first: usize) -> Result<Vec<Belief>, EstimatorError> {
    let Some(last) = steps.last() else { return Ok(Vec::new()) };
    let mut smoothed = vec![last.posterior; steps.len()];
    for k in (0..steps.len() - 1).rev() {
        smoothed[k] = smooth_step(&steps[k].posterior, &steps[k + 1], &smoothed[k + 1])
            .ok_or(EstimatorError::SingularPrior { step: first + k + 1 })?;
    }
    Ok(smoothed)
}

/// One smoothing step (eq. 2.143) from the filtered belief `filtered` at
/// `k`, the forward pass's step `following` at `k + 1` and the smoothed
/// belief `next` there.
fn smooth_step(filtered: &Belief, following: &Step, next: &Belief) -> Option<Belief> {
    let prior = &following.prior;
    // Translation, the three axes at once: mu^s = mu + G (mu^s_k+1 - mu^-_k+1).
    let P = &filtered.P_translation;
    let G = gain(P, &following.F_translation, &prior.P_translation)?;
    let translation = filtered.translation + G * (next.translation - prior.translation);
    let P_translation = P + G * (next.P_translation - prior.P_translation) * G.transpose();
    // Orientation: the same in the tangent space of the prediction at k + 1,
    // the correction retracted at the filtered nominal at k.
    let P = &filtered.P_rotation;
    let G = gain(P, &following.F_rotation, &prior.P_rotation)?;
    let dtheta = ominus(&next.orientation, &prior.orientation);
    let domega = next.angular_velocity - prior.angular_velocity;
    let d = G * Vector6::new(dtheta.x, dtheta.y, dtheta.z, domega.x, domega.y, domega.z);
    let mut orientation = exp(&Vector3::new(d[0], d[1], d[2])) * filtered.orientation;
    orientation.renormalize_fast();
    let P_rotation = P + G * (next.P_rotation - prior.P_rotation) * G.transpose();
    Some(Belief {
        translation,
        P_translation: symmetric(P_translation),
        orientation,
        angular_velocity: filtered.angular_velocity + Vector3::new(d[3], d[4], d[5]),
        P_rotation: symmetric(P_rotation),
    })
}

/// `G = P F^T (P^-)^-1`, solved through the Cholesky factor of the prior
/// covariance `P^-` (or its inverse when rounding made it indefinite), as
/// [`crate::rts::smooth`] does; `None` when it is singular.
fn gain<const N: usize>(
    P: &SMatrix<f64, N, N>,
    F: &SMatrix<f64, N, N>,
    P_prior: &SMatrix<f64, N, N>,
) -> Option<SMatrix<f64, N, N>> {
    // G P^- = P F^T  <=>  P^- G^T = F P  (both covariances symmetric).
    let rhs = F * P;
    let Gt = match P_prior.cholesky() {
        Some(chol) => chol.solve(&rhs),
        None => P_prior.try_inverse()? * rhs,
    };
    Gt.iter().all(|v| v.is_finite()).then(|| Gt.transpose())
}
