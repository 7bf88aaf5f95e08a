//! The constant-velocity model of a position along one axis (thesis Sec.
//! 6.2.3, eqs. 6.12-6.15), defined once and used three ways: the causal
//! filter of live tracking ([`CvFilter`]), the Kalman filter and RTS
//! smoother that turn marker positions into ground truth
//! ([`CvParams::smooth`]), and the maximum-likelihood tuning of its noise
//! ([`tune`]).
//!
//! State `x = (p, v)` (eq. 6.12): position along the sliding axis (m) and
//! velocity (m/s). Motion (eq. 6.13): `p_k = p_k-1 + v_k-1 dt`, `v_k =
//! v_k-1`, plus `w ~ N(0, Q(dt))`. Measurement (eq. 6.14): `z = p + nu`,
//! `nu ~ N(0, R)`. Samples may come at any times; a sample without a
//! measurement is a predict-only step.
//!
//! # Units and the scaling of `Q` with the step
//! The thesis gives `Q = diag(0.01, 0.01)` per step at the camera's 30 Hz and
//! `R = 10`. Here `Q` is a rate: `Q(dt) = diag(q_p, q_v) * dt` with the
//! spectral densities `q_p` (m^2/s) and `q_v` ((m/s)^2/s) of independent
//! random walks on position and velocity. A process sampled twice as often
//! then gets half the noise per step and the same noise per second, so the
//! smoothing does not depend on the sample rate (100 Hz tactile times with
//! 30 Hz marker measurements in between, or the camera's own times). At
//! `dt = 1/30 s`, `Q(dt) = diag(q_p, q_v) / 30`: the thesis's numbers are
//! `q_p = q_v = 0.3`, `R = 10` in any length unit, because the smoothed mean
//! depends only on the ratios of `Q`, `R` and `P0` (see
//! [`CvParams::from_per_step`]).
//!
//! # One model, two forms
//! [`CvParams::transition`] and [`CvParams::measurement`] give the model as
//! matrices for the generic Kalman filter of [`crate::rts`] (the causal
//! filter and the smoother's forward pass). The tuner's likelihood, run
//! thousands of times per tuning, uses the same `F(dt)`, `Q(dt)`, `H` and
//! `R` written out for two states and one measurement ([`expanded`]); the
//! tests check that both forms give the same beliefs.
#![expect(non_snake_case, reason = "matrices are named as in the thesis's equations (F, H, Q, R, P, K)")]

mod expanded;
mod filter;
mod params;
mod smoother;
pub mod tune;

#[cfg(test)]
mod tests;

pub use filter::CvFilter;
pub use params::CvParams;
pub use smoother::{CvSample, CvTrack};
