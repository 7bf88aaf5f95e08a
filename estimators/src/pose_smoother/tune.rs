//! The six noise densities of the pose smoother estimated from the marker
//! poses alone: maximum of the summed gated log-likelihood
//! ([`super::log_likelihood`]) over sequences, under the rules of
//! [`crate::constant_velocity::tune`] (robust gated likelihood, the gate's re-acquisition
//! left out, log scale, Nelder-Mead restarted from its best point).
//!
//! # Two blocks of three
//! The likelihood is a sum of a translation term (depending on `q_p`, `q_v`,
//! `r_p`) and an orientation term (`q_theta`, `q_omega`, `r_theta`): the
//! two filters share nothing but the gate's decisions. So the search
//! alternates between the two blocks, each a three-parameter Nelder-Mead
//! ([`crate::constant_velocity::tune`]'s) with the other block held. Without a gate the
//! objective is separable and one round is the joint optimum; with one, a
//! pose rejected for its orientation also drops its position, so the rounds
//! repeat until one gains less than 1e-3 in log-likelihood (at most
//! [`MAX_ROUNDS`]): block-coordinate ascent of the joint likelihood.
//!
//! # Bounds
//! Every density is kept in [`SEARCH_BOX`] (the log-parameter is clamped
//! before it is used): a density the data cannot see (a position walk
//! hidden under the marker noise, a rotation that never changes speed) runs
//! to the edge of the box and stops there with finite, usable parameters,
//! instead of running to 0 or infinity and producing NaN.

use rayon::prelude::*;

use super::filter::log_likelihood;
use super::types::{PoseSample, PoseSmootherParams};
use crate::constant_velocity::tune::nelder_mead_restarted;

/// The interval every tuned density stays in, in the SI unit of each (m^2/s,
/// m^2/s^3, m^2, rad^2/s, rad^2/s^3, rad^2): from a standard deviation of
/// 1e-12 to 1e3 per unit.
pub const SEARCH_BOX: [f64; 2] = [1e-24, 1e6];

/// Rounds of block-coordinate ascent at most, with a gate.
const MAX_ROUNDS: usize = 6;

/// The tuned parameters and how they were found.
#[derive(Clone, Debug, PartialEq)]
pub struct TunedPoseNoise {
    /// The parameters: the six densities estimated, `P0` and the gate as given.
    pub params: PoseSmootherParams,
    /// The summed log-likelihood of the measurements at `params`.
    pub log_likelihood: f64,
    /// Marker poses used.
    pub measurements: usize,
    /// Likelihood evaluations (each over all sequences).
    pub evaluations: usize,
    /// Rounds over the two blocks.
    pub rounds: usize,
}

/// One block of three densities.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Block {
    /// `q_p`, `q_v`, `r_p`.
    Translation,
    /// `q_theta`, `q_omega`, `r_theta`.
    Rotation,
}

/// The block's densities, as logarithms.
fn logs(p: &PoseSmootherParams, block: Block) -> [f64; 3] {
    let v = match block {
        Block::Translation => [p.q_position_m2_per_s, p.q_velocity_m2_per_s3, p.r_position_m2],
        Block::Rotation => {
            [p.q_orientation_rad2_per_s, p.q_angular_velocity_rad2_per_s3, p.r_orientation_rad2]
        }
    };
    v.map(f64::ln)
}

/// `p` with the block's densities `exp(v)`, each clamped into
/// [`SEARCH_BOX`] (a NaN, from a start at a non-positive density, to its
/// lower end).
fn with(p: &PoseSmootherParams, block: Block, v: &[f64; 3]) -> PoseSmootherParams {
    let [lo, hi] = SEARCH_BOX.map(f64::ln);
    let [a, b, c] = v.map(|x| if x.is_nan() { lo } else { x.clamp(lo, hi) }.exp());
    match block {
        Block::Translation => {
            PoseSmootherParams { q_position_m2_per_s: a, q_velocity_m2_per_s3: b, r_position_m2: c, ..*p }
        }
        Block::Rotation => PoseSmootherParams {
            q_orientation_rad2_per_s: a,
            q_angular_velocity_rad2_per_s3: b,
            r_orientation_rad2: c,
            ..*p
        },
    }
}

/// The six densities of `start` replaced by those that maximise the summed
/// log-likelihood of the marker poses of `sequences` (each a session, times
/// strictly increasing, each filtered from its own first pose), searched
/// from `start`'s values. `P0` and the gate stay as given. A sequence whose
/// times do not increase makes every candidate `-inf`: `start` (clamped into
/// [`SEARCH_BOX`]) comes back with that likelihood.
pub fn tune_pose_noise(start: &PoseSmootherParams, sequences: &[&[PoseSample]]) -> TunedPoseNoise {
    // Per-sequence terms in parallel, summed in sequence order (repeatable).
    let total = |p: &PoseSmootherParams| -> f64 {
        let terms: Vec<f64> = sequences.par_iter().map(|s| log_likelihood(p, s)).collect();
        terms.iter().sum()
    };
    let mut params = *start;
    for block in [Block::Translation, Block::Rotation] {
        params = with(&params, block, &logs(&params, block));
    }
    let (mut best, mut evaluations, mut rounds) = (total(&params), 1, 0);
    while rounds < MAX_ROUNDS {
        rounds += 1;
        let before = best;
        for block in [Block::Translation, Block::Rotation] {
            let (p, l, used) = tune_block(&params, block, &total);
            evaluations += used;
            if l > best {
                (params, best) = (p, l);
            }
        }
        let gained = best - before;
        if params.gate.is_none() || gained.is_nan() || gained < 1e-3 {
            break;
        }
    }
    TunedPoseNoise {
        params,
        log_likelihood: best,
        measurements: sequences.iter().flat_map(|s| s.iter()).filter(|s| s.measurement.is_some()).count(),
        evaluations,
        rounds,
    }
}

/// The block's densities that maximise `total` with the rest of `params`
/// held: Nelder-Mead restarted from its best point with a fresh simplex a
/// decade wide until a restart gains less than 1e-3, as
/// [`crate::constant_velocity::tune::tune_noise_jointly`]. Returns the parameters, their
/// log-likelihood and the evaluations used.
fn tune_block(
    params: &PoseSmootherParams,
    block: Block,
    total: &impl Fn(&PoseSmootherParams) -> f64,
) -> (PoseSmootherParams, f64, usize) {
    let cost = |v: &[f64; 3]| {
        let l = total(&with(params, block, v));
        if l.is_finite() { -l } else { f64::INFINITY }
    };
    let (best, best_cost, evaluations) = nelder_mead_restarted(&cost, logs(params, block));
    (with(params, block, &best), -best_cost, evaluations)
}
