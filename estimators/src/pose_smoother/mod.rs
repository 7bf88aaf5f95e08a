//! A constant-velocity RTS smoother for a full 6-DoF pose: the ground truth
//! of an object's pose in the hand from noisy marker poses (ArUco,
//! `camera_from_object`), the 6-DoF counterpart of [`crate::constant_velocity`]
//! (thesis Sec. 6.2.3, Algorithm 10), with orientation handled as in thesis
//! Sec. 2.3.2 (unit quaternions, Algorithm 9's operators).
//!
//! # Model
//! All vectors are in the measurement frame ("world": the camera or hand
//! frame the marker poses are given in).
//!
//! - Translation: position `p` (m) and velocity `v` (m/s) of the object
//!   origin, constant velocity on each axis exactly as [`crate::constant_velocity`]:
//!   `F(dt) = [[1, dt], [0, 1]]`, `Q(dt) = diag(q_p, q_v) dt`, `H = [1, 0]`,
//!   `R = r_p`, the same densities on the three independent axes.
//! - Orientation: `q = frame_from_object` and the angular velocity `omega`
//!   (rad/s) in the measurement frame, constant: `q_k = Exp(omega dt) q_k-1`
//!   (left-multiplied, i.e. `dq/dt = 1/2 omega ⊗ q`, the spatial angular
//!   velocity). It is filtered as an error-state (multiplicative) EKF: the
//!   nominal `(q, omega)` carries the mean, the Gaussian lives on the error
//!   `(dtheta, domega)` with `q_true = Exp(dtheta) q` (a perturbation in the
//!   measurement frame, the thesis's `q ⊕ dtheta`, eq. 2.114) and
//!   `omega_true = omega + domega`. To first order in the errors
//!   ```text
//!   dtheta_k = Exp(omega dt) dtheta_k-1 + J_l(omega dt) dt domega_k-1 + w_theta
//!   domega_k = domega_k-1 + w_omega
//!   ```
//!   with the left Jacobian `J_l` of SO(3) (Solà et al. 2018, App. B), so
//!   `F = [[Exp(omega dt), J_l(omega dt) dt], [0, I]]`, and
//!   `Q(dt) = diag(q_theta I, q_omega I) dt`, the translation's convention on
//!   the tangent coordinates. The measurement innovation is
//!   `y = Log(q_meas q_pred^-1)` (the thesis's `q_meas ⊖ q_pred`, eq. 2.115),
//!   whose logarithm takes the scalar part non-negative first, so `q` and
//!   `-q` give the same innovation and the shortest rotation is used; `H =
//!   [I 0]`, `R = r_theta I`. After the correction the error mean is moved
//!   into the nominal (`q <- Exp(dtheta) q`, `omega <- omega + domega`) and
//!   reset to zero; the reset's Jacobian (`I - [dtheta/2]x`) is taken as `I`,
//!   an error of second order in the correction.
//!
//! The 12-D state's covariance is block diagonal between translation and
//! orientation at every step (`F`, `Q`, `H`, `R` and `P0` all are), and the
//! translation block is `P ⊗ I3`: the three axes share `F`, `Q`, `H`, `R`,
//! `P0` and every accept/reject decision, so one 2x2 covariance serves them
//! all (the implementation keeps that 2x2 matrix and a 6x6 one).
//!
//! # The smoother
//! The backward pass is the extended RTS smoother (Särkkä, *Bayesian
//! Filtering and Smoothing*, 2013, Sec. 9.1; thesis eq. 2.143) written on
//! the manifold: with the filtered `x_k`, the predicted `x-_k+1`, `F_k+1` and
//! the smoothed `xs_k+1`,
//! ```text
//! G_k   = P_k F_k+1^T (P-_k+1)^-1
//! d_k   = G_k (xs_k+1 ⊟ x-_k+1),   xs_k = x_k ⊞ d_k
//! Ps_k  = P_k + G_k (Ps_k+1 - P-_k+1) G_k^T
//! ```
//! where `⊟` is `(Log(q_a q_b^-1), omega_a - omega_b)` and `⊞` is
//! `(Exp(dtheta) q, omega + domega)`. Approximations: `F` is linearised at
//! the filtered nominal (not re-linearised at the smoothed one); the
//! covariances `Ps_k+1` and `P-_k+1` are tangent at different nominals and
//! are subtracted as if they were tangent at the same one, and `Ps_k` is
//! reported in the tangent space of the filtered `q_k`, not of the smoothed
//! one (both differ by a rotation of the size of the smoothing correction,
//! a fraction of the measurement noise here). For the translation every
//! step is exact: the equations of [`crate::rts::smooth`].
//!
//! # Start, gaps, gate
//! The filter starts at the first sample with a measurement: its prior is
//! that pose with zero velocities and covariance `P0`, which the measurement
//! then corrects like any other (with `P0 >> R` the usual diffuse start; as
//! [`crate::constant_velocity`] with `x0` at the first measured position). Samples
//! before it get a copy of its filtered and smoothed estimate (the pose held,
//! not extrapolated backwards). A sample without a measurement is a
//! predict-only step. The gate acts on the 6-D pose innovation as a whole
//! (a marker pose is accepted or rejected, never half of it): its squared
//! Mahalanobis distance is that of the position plus that of the
//! orientation (the innovation covariance is block diagonal), chi-square
//! with 6 degrees of freedom for an inlier. See [`POSE_GATE_MAHALANOBIS2`].
#![expect(non_snake_case, reason = "matrices are named as in the thesis's equations (F, H, Q, R, P, K, G)")]

mod filter;
mod smoother;
mod so3;
mod tune;
mod types;

#[cfg(test)]
mod tests;
#[cfg(test)]
mod tests_tune;

pub use filter::log_likelihood;
pub use tune::{SEARCH_BOX, TunedPoseNoise, tune_pose_noise};
pub use types::{POSE_GATE_MAHALANOBIS2, PoseMeasurement, PoseSample, PoseSmootherParams, SmoothedPose};

use crate::EstimatorError;
use crate::rts::MeasurementUse;
use filter::Belief;

/// The filter's and the smoother's estimates at every sample.
#[derive(Clone, Debug, PartialEq)]
pub struct PoseSmoothing {
    /// `p(x_k | z_1:k)`: the causal filter's estimate, one per sample.
    pub filtered: Vec<SmoothedPose>,
    /// `p(x_k | z_1:T)`: the smoother's estimate, the ground truth.
    pub smoothed: Vec<SmoothedPose>,
    /// What each sample's measurement was used for (`Missing` without one),
    /// with its squared Mahalanobis distance against the prediction.
    pub measurements: Vec<MeasurementUse>,
}

/// Runs the filter and the smoother over `samples` (times strictly
/// increasing). All three vectors are empty when no sample has a
/// measurement (there is no pose to start from). Fails on a time that does
/// not increase or is not finite ([`EstimatorError::TimeNotIncreasing`]), a
/// non-finite measurement, or a singular covariance.
pub fn smooth_poses(
    params: &PoseSmootherParams,
    samples: &[PoseSample],
) -> Result<PoseSmoothing, EstimatorError> {
    let mut steps = Vec::with_capacity(samples.len());
    let run = filter::forward(params, params.gate, samples, |step| steps.push(step))?;
    let Some(first) = run.first_measured else {
        return Ok(PoseSmoothing { filtered: Vec::new(), smoothed: Vec::new(), measurements: Vec::new() });
    };
    let smoothed = smoother::smooth(&steps, first)?;
    let filtered: Vec<Belief> = steps.iter().map(|s| s.posterior).collect();
    let mut measurements = vec![MeasurementUse::Missing; first];
    measurements.extend(steps.iter().map(|s| s.measurement));
    Ok(PoseSmoothing {
        filtered: track(samples, first, &filtered),
        smoothed: track(samples, first, &smoothed),
        measurements,
    })
}

/// One estimate per sample from the beliefs of the samples from `first` on;
/// the samples before `first` get its estimate.
fn track(samples: &[PoseSample], first: usize, beliefs: &[Belief]) -> Vec<SmoothedPose> {
    samples.iter().enumerate().map(|(k, s)| beliefs[k.saturating_sub(first)].estimate(s.t_s)).collect()
}
