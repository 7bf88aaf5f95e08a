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

#[cfg(test)]
mod tests;
#[cfg(test)]
mod tests_tune;

use nalgebra::{SMatrix, UnitQuaternion, Vector3};

pub use tune::{SEARCH_BOX, TunedPoseNoise, tune_pose_noise};

use crate::EstimatorError;
use crate::rts::{Gate, MeasurementUse};
use filter::Belief;

/// The default gate on the squared Mahalanobis distance of the 6-D pose
/// innovation: the chi-square quantile with 6 degrees of freedom of the tail
/// probability 5.7e-7 that the 1-D gate of 25 (5 sigma) of the marker
/// positions has, so an inlier marker pose is rejected as rarely as a
/// position is there. (The 99.9 % quantile would be 22.5; an ArUco
/// orientation flip of 30 degrees at 1 degree of noise lies in the hundreds.)
pub const POSE_GATE_MAHALANOBIS2: f64 = 39.5;

/// One sample time, with the marker pose measured there if any.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PoseSample {
    /// Time (s), strictly increasing along a sequence.
    pub t_s: f64,
    /// The measured pose, `None` for a predict-only step.
    pub measurement: Option<PoseMeasurement>,
}

/// A measured pose `frame_from_object`: where the object is in the
/// measurement frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PoseMeasurement {
    /// Position of the object origin in the measurement frame (m).
    pub position_m: Vector3<f64>,
    /// Rotation `frame_from_object` (either sign of the quaternion).
    pub orientation: UnitQuaternion<f64>,
}

/// The parameters of the pose smoother, in SI units. The densities scale
/// `Q` with the step as in [`crate::constant_velocity`]: `Q(dt) = q dt`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PoseSmootherParams {
    /// Spectral density of the position random walk, per axis, `q_p` (m^2/s).
    pub q_position_m2_per_s: f64,
    /// Spectral density of the velocity random walk, per axis, `q_v` (m^2/s^3).
    pub q_velocity_m2_per_s3: f64,
    /// Variance of one measured position coordinate, `r_p` (m^2).
    pub r_position_m2: f64,
    /// Spectral density of the orientation random walk, per tangent axis,
    /// `q_theta` (rad^2/s).
    pub q_orientation_rad2_per_s: f64,
    /// Spectral density of the angular-velocity random walk, per axis,
    /// `q_omega` (rad^2/s^3).
    pub q_angular_velocity_rad2_per_s3: f64,
    /// Variance of one measured orientation tangent coordinate, `r_theta`
    /// (rad^2; the angle error is about `sqrt(3 r_theta)`).
    pub r_orientation_rad2: f64,
    /// Initial position variance per axis (m^2).
    pub p0_position_m2: f64,
    /// Initial velocity variance per axis (m^2/s^2).
    pub p0_velocity_m2_per_s2: f64,
    /// Initial orientation variance per tangent axis (rad^2).
    pub p0_orientation_rad2: f64,
    /// Initial angular-velocity variance per axis (rad^2/s^2).
    pub p0_angular_velocity_rad2_per_s2: f64,
    /// Innovation gate on the 6-D pose innovation; `None` accepts every pose.
    pub gate: Option<Gate>,
}

impl Default for PoseSmootherParams {
    /// A marker pose noise of 1 mm and 1 degree per axis; velocity changes
    /// of 1 cm/s and angular-velocity changes of 0.3 rad/s per root second,
    /// small walks of the pose itself; a diffuse start (the measurement's
    /// variance on the pose, 0.1 m/s and 1 rad/s on the velocities); the
    /// gate at [`POSE_GATE_MAHALANOBIS2`], never re-acquiring.
    fn default() -> Self {
        let one_degree = 1f64.to_radians();
        PoseSmootherParams {
            q_position_m2_per_s: 1e-8,
            q_velocity_m2_per_s3: 1e-4,
            r_position_m2: 1e-6,
            q_orientation_rad2_per_s: 1e-5,
            q_angular_velocity_rad2_per_s3: 0.1,
            r_orientation_rad2: one_degree * one_degree,
            p0_position_m2: 1e-6,
            p0_velocity_m2_per_s2: 1e-2,
            p0_orientation_rad2: one_degree * one_degree,
            p0_angular_velocity_rad2_per_s2: 1.0,
            gate: Some(Gate::at(POSE_GATE_MAHALANOBIS2)),
        }
    }
}

/// The estimate at one sample.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SmoothedPose {
    /// Time (s).
    pub t_s: f64,
    /// Position of the object origin, measurement frame (m).
    pub position_m: Vector3<f64>,
    /// Its velocity, measurement frame (m/s).
    pub velocity_m_per_s: Vector3<f64>,
    /// Rotation `frame_from_object`. Its sign is continuous along the track,
    /// starting from the first measurement's: compare rotations, not
    /// components.
    pub orientation: UnitQuaternion<f64>,
    /// Angular velocity, measurement frame (rad/s): `q(t + dt) ≈
    /// Exp(omega dt) q(t)`.
    pub angular_velocity_rad_per_s: Vector3<f64>,
    /// Covariance of the tangent error `(dp (m), dv (m/s), dtheta (rad),
    /// domega (rad/s))`, three coordinates each in that order, with
    /// `q_true = Exp(dtheta) q` (measurement frame).
    pub covariance: SMatrix<f64, 12, 12>,
}

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

/// `log p(z_1:T)` of the marker poses of `samples` under `params`, the
/// gated robust form of [`crate::constant_velocity::tune`]: each pose adds the Gaussian
/// log-density of its 6-D innovation, a pose beyond the gate adds the term
/// at the gate's edge `-1/2 (log det(2 pi S) + d2_max)` and is not used. As
/// there, the gate's re-acquisition is left out (the likelihood is that of a
/// gate that never opens). The first pose's innovation is zero (it centres
/// the prior) and adds `-1/2 log det(2 pi (P0 + R))`. `-inf` when the filter
/// fails (a time that does not increase, a non-finite measurement, a
/// covariance that stops being positive); 0 without measurements.
pub fn log_likelihood(params: &PoseSmootherParams, samples: &[PoseSample]) -> f64 {
    let gate = params.gate.map(|g| Gate { reacquire_after: None, ..g });
    match filter::forward(params, gate, samples, |_| ()) {
        Ok(run) if !run.log_likelihood.is_nan() => run.log_likelihood,
        _ => f64::NEG_INFINITY,
    }
}
