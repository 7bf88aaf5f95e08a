//! The constant-velocity model's noise parameters estimated from the marker
//! positions alone: maximum marginal likelihood of the measurements under
//! the model (thesis eqs. 6.12-6.14), so that a rig without a simulator's
//! truth can choose them for the ground-truth smoother.
//!
//! The Kalman filter's innovations `nu_k ~ N(0, S_k)` factor the likelihood
//! of the measurements (Särkkä, *Bayesian Filtering and Smoothing*, eq.
//! 12.11): `log p(z_1:T) = -1/2 sum_k (log(2 pi S_k) + nu_k^2 / S_k)`. With
//! the innovation gate a rejected position adds the term at the gate's edge,
//! `-1/2 (log(2 pi S_k) + d2_max)` (a likelihood robust to outliers), so
//! that shrinking `R` to reject more positions never pays.
//!
//! The gate's re-acquisition ([`crate::rts::Gate::reacquire_after`]) is left
//! out: the likelihood is that of a gate that never opens. It is a safeguard
//! of the labelling against a filter locked out by a real jump, not part of
//! the noise model, and with it the likelihood has the degenerate optimum of
//! no gate at all (on simulated sessions `R` -> 1e-17 m^2, following every
//! marker position, and the velocity error 1.2 mm/s instead of 0.13). The three
//! densities are found on a log scale by Nelder-Mead: three parameters and a
//! smooth objective do not warrant an optimisation crate.

use super::expanded::ExpandedBelief;
use super::params::CvParams;
use super::smoother::CvSample;

/// The tuned parameters and how they were found.
#[derive(Clone, Debug, PartialEq)]
pub struct TunedNoise {
    /// The parameters: `q_p`, `q_v` and `R` estimated; the rest as given.
    pub params: CvParams,
    /// The log-likelihood of the measurements at `params`.
    pub log_likelihood: f64,
    /// Marker positions used.
    pub measurements: usize,
    /// Likelihood evaluations.
    pub evaluations: usize,
}

/// `log p(z_1:T)` of the measurements of `samples` under `params` (the
/// gated, robust form of the module documentation). `-inf` when a
/// covariance stops being positive.
pub fn log_likelihood(params: &CvParams, samples: &[CvSample]) -> f64 {
    let two_pi = std::f64::consts::TAU;
    let mut belief = ExpandedBelief::initial(params);
    let mut sum = 0.0;
    let gate = params.gate.map(|g| g.max_mahalanobis2);
    let mut previous: Option<f64> = None;
    for s in samples {
        if let Some(t0) = previous {
            belief.predict(params, s.t_s - t0);
        }
        previous = Some(s.t_s);
        let Some(z) = s.z_m else { continue };
        let (nu, s_var) = belief.innovation(params, z);
        if !(s_var > 0.0 && s_var.is_finite()) {
            return f64::NEG_INFINITY;
        }
        let d2 = nu * nu / s_var;
        if let Some(max) = gate
            && d2 > max
        {
            sum -= 0.5 * ((two_pi * s_var).ln() + max);
            continue;
        }
        sum -= 0.5 * ((two_pi * s_var).ln() + d2);
        belief.correct(nu, s_var);
    }
    sum
}

/// `q_p`, `q_v` and `R` of `start` replaced by the values that maximise the
/// likelihood of the measurements in `samples` (times strictly increasing),
/// searched from `start`'s values. The gate, `x0` and `P0` stay as given.
pub fn tune_noise(start: &CvParams, samples: &[CvSample]) -> TunedNoise {
    tune_noise_jointly(start, &[samples])
}

/// [`tune_noise`] over several independent sequences at once (sessions of
/// one rig and marker): the parameters that maximise the sum of their
/// log-likelihoods, each sequence filtered from `start`'s `x0` and `P0`.
/// One estimate from many sequences is steadier than one per sequence
/// where a sequence holds little motion or few marker positions.
pub fn tune_noise_jointly(start: &CvParams, sequences: &[&[CvSample]]) -> TunedNoise {
    let with = |v: &[f64; 3]| CvParams {
        q_position_m2_per_s: v[0].exp(),
        q_velocity_m2_per_s3: v[1].exp(),
        r_m2: v[2].exp(),
        ..*start
    };
    let total = |params: &CvParams| sequences.iter().map(|s| log_likelihood(params, s)).sum::<f64>();
    let cost = |v: &[f64; 3]| {
        let l = total(&with(v));
        if l.is_finite() { -l } else { f64::INFINITY }
    };
    let start_logs = [start.q_position_m2_per_s.ln(), start.q_velocity_m2_per_s3.ln(), start.r_m2.ln()];
    let (best, _, evaluations) = nelder_mead_restarted(&cost, start_logs);
    let params = with(&best);
    TunedNoise {
        log_likelihood: total(&params),
        params,
        measurements: sequences.iter().flat_map(|s| s.iter()).filter(|s| s.z_m.is_some()).count(),
        evaluations,
    }
}

/// Minimises `cost` from `start` (three log densities) with Nelder-Mead,
/// restarted from its best point with a fresh, large simplex until a
/// restart gains under 1e-3 (at most 8 runs): Nelder-Mead stalls on the
/// ridge where a random walk's density and the measurement noise trade off,
/// and a restart moves it on. Returns the best point, its cost and the
/// number of cost evaluations.
pub(crate) fn nelder_mead_restarted(
    cost: &impl Fn(&[f64; 3]) -> f64,
    start: [f64; 3],
) -> ([f64; 3], f64, usize) {
    let mut best = start;
    let (mut best_cost, mut evaluations) = (cost(&best), 1);
    for _ in 0..8 {
        let (x, used) = nelder_mead(cost, best, 10f64.ln(), 1e-6, 2000);
        evaluations += used;
        let c = cost(&x);
        let gained = best_cost - c;
        if c < best_cost {
            (best, best_cost) = (x, c);
        }
        if gained.is_nan() || gained < 1e-3 {
            break;
        }
    }
    (best, best_cost, evaluations)
}

/// Minimises `f` from `x0` with the Nelder-Mead simplex (reflection 1,
/// expansion 2, contraction and shrink 1/2), the first simplex `step` away
/// along each axis; stops when the simplex's values differ by less than
/// `tolerance` or after `max_evaluations`. Returns the best point and the
/// evaluations used.
pub(crate) fn nelder_mead(
    f: &impl Fn(&[f64; 3]) -> f64,
    x0: [f64; 3],
    step: f64,
    tolerance: f64,
    max_evaluations: usize,
) -> ([f64; 3], usize) {
    let mut simplex: Vec<([f64; 3], f64)> = (0..4)
        .map(|i| {
            let mut x = x0;
            if i > 0 {
                x[i - 1] += step;
            }
            (x, f(&x))
        })
        .collect();
    let mut evaluations = 4;
    let along =
        |a: &[f64; 3], b: &[f64; 3], t: f64| -> [f64; 3] { [0, 1, 2].map(|j| a[j] + t * (b[j] - a[j])) };
    while evaluations < max_evaluations {
        simplex.sort_by(|a, b| a.1.total_cmp(&b.1));
        if (simplex[3].1 - simplex[0].1).abs() <= tolerance {
            break;
        }
        let centroid = [0, 1, 2].map(|j| simplex[..3].iter().map(|(x, _)| x[j]).sum::<f64>() / 3.0);
        let worst = simplex[3];
        let reflected = along(&centroid, &worst.0, -1.0);
        let fr = f(&reflected);
        evaluations += 1;
        if fr < simplex[0].1 {
            let expanded = along(&centroid, &worst.0, -2.0);
            let fe = f(&expanded);
            evaluations += 1;
            simplex[3] = if fe < fr { (expanded, fe) } else { (reflected, fr) };
        } else if fr < simplex[2].1 {
            simplex[3] = (reflected, fr);
        } else {
            let contracted = if fr < worst.1 {
                along(&centroid, &reflected, 0.5)
            } else {
                along(&centroid, &worst.0, 0.5)
            };
            let fc = f(&contracted);
            evaluations += 1;
            if fc < worst.1.min(fr) {
                simplex[3] = (contracted, fc);
            } else {
                let best = simplex[0].0;
                for v in simplex.iter_mut().skip(1) {
                    v.0 = along(&best, &v.0, 0.5);
                    v.1 = f(&v.0);
                }
                evaluations += 3;
            }
        }
    }
    simplex.sort_by(|a, b| a.1.total_cmp(&b.1));
    (simplex[0].0, evaluations)
}

#[cfg(test)]
mod tests {
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;
    use rand_distr::{Distribution, Normal};

    use super::*;

    /// Positions of the constant-velocity model itself at 30 Hz, with the
    /// densities `q` and the noise `r`.
    fn simulated(q: [f64; 2], r: f64, n: usize, seed: u64) -> Vec<CvSample> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let dt = 1.0 / 30.0;
        let (wp, wv) =
            (Normal::new(0.0, (q[0] * dt).sqrt()).unwrap(), Normal::new(0.0, (q[1] * dt).sqrt()).unwrap());
        let noise = Normal::new(0.0, r.sqrt()).unwrap();
        let (mut p, mut v) = (0.0, 0.0);
        (0..n)
            .map(|k| {
                if k > 0 {
                    p += v * dt + wp.sample(&mut rng);
                    v += wv.sample(&mut rng);
                }
                CvSample { t_s: k as f64 * dt, z_m: Some(p + noise.sample(&mut rng)) }
            })
            .collect()
    }

    #[test]
    fn the_likelihood_is_the_gaussian_of_the_first_innovation() {
        let params = CvParams { gate: None, ..CvParams::default() };
        let z = 0.03;
        let s = params.p0_diag[0] + params.r_m2;
        let expected = -0.5 * ((std::f64::consts::TAU * s).ln() + z * z / s);
        let got = log_likelihood(&params, &[CvSample { t_s: 0.0, z_m: Some(z) }]);
        assert!((got - expected).abs() < 1e-12, "{got} vs {expected}");
    }

    #[test]
    fn the_densities_that_made_the_data_are_found_again() {
        // Marker noise 0.5 mm, velocity changes of 10 mm/s per root second.
        let (q, r) = ([1e-9, 1e-4], 2.5e-7);
        let samples = simulated(q, r, 6000, 3);
        // Start a decade or more away from each.
        let start = CvParams {
            q_position_m2_per_s: 1e-7,
            q_velocity_m2_per_s3: 1e-6,
            r_m2: 1e-5,
            ..Default::default()
        };
        let tuned = tune_noise(&start, &samples);
        let p = &tuned.params;
        assert!((p.r_m2 / r - 1.0).abs() < 0.15, "R {} vs {r}", p.r_m2);
        assert!(
            (p.q_velocity_m2_per_s3 / q[1] - 1.0).abs() < 0.3,
            "q_v {} vs {}",
            p.q_velocity_m2_per_s3,
            q[1]
        );
        // The position walk is small beside the noise (0.02 mm per step
        // against 0.5 mm): the estimate may not find it, but keeps it small.
        assert!(p.q_position_m2_per_s / 30.0 < 0.05 * r, "q_p {}", p.q_position_m2_per_s);
        assert!(
            tuned.log_likelihood
                >= log_likelihood(
                    &CvParams { q_position_m2_per_s: q[0], q_velocity_m2_per_s3: q[1], r_m2: r, ..start },
                    &samples
                ) - 1e-6
        );
    }

    /// Five short sequences of one model: jointly, the densities are found
    /// again and the likelihood is the sum of the sequences'; the shortest
    /// one alone (8 s) misses the velocity density by far more.
    #[test]
    fn several_sequences_are_tuned_jointly_as_one_model() {
        let (q, r) = ([1e-9, 1e-4], 2.5e-7);
        let sequences: Vec<Vec<CvSample>> = [1200, 1200, 1200, 1200, 240]
            .iter()
            .zip(10..)
            .map(|(&n, seed)| simulated(q, r, n, seed))
            .collect();
        let slices: Vec<&[CvSample]> = sequences.iter().map(Vec::as_slice).collect();
        let start = CvParams {
            q_position_m2_per_s: 1e-7,
            q_velocity_m2_per_s3: 1e-6,
            r_m2: 1e-5,
            ..Default::default()
        };
        let joint = tune_noise_jointly(&start, &slices);
        let p = &joint.params;
        let q_v_error = |p: &CvParams| (p.q_velocity_m2_per_s3 / q[1]).ln().abs();
        assert!((p.r_m2 / r - 1.0).abs() < 0.15, "R {} vs {r}", p.r_m2);
        assert!(q_v_error(p) < 0.3_f64.ln_1p(), "q_v {} vs {}", p.q_velocity_m2_per_s3, q[1]);
        assert_eq!(joint.measurements, 5040);
        let sum: f64 = slices.iter().map(|s| log_likelihood(p, s)).sum();
        assert!((joint.log_likelihood - sum).abs() < 1e-9, "{} vs {sum}", joint.log_likelihood);
        // One sequence alone is the same function as before.
        assert_eq!(tune_noise(&start, slices[0]), tune_noise_jointly(&start, &slices[..1]));
        let short = tune_noise(&start, slices[4]);
        eprintln!(
            "jointly: R {:.3e}, q_v {:.3e}; the 8 s sequence alone: R {:.3e}, q_v {:.3e}",
            p.r_m2, p.q_velocity_m2_per_s3, short.params.r_m2, short.params.q_velocity_m2_per_s3
        );
        assert!(
            q_v_error(&short.params) > 2.0 * q_v_error(p),
            "the 8 s sequence alone: q_v {} against {} jointly",
            short.params.q_velocity_m2_per_s3,
            p.q_velocity_m2_per_s3
        );
    }

    #[test]
    fn outliers_behind_the_gate_do_not_drag_the_noise_up() {
        let (q, r) = ([1e-9, 1e-4], 2.5e-7);
        let mut samples = simulated(q, r, 3000, 5);
        for s in samples.iter_mut().skip(50).step_by(97) {
            s.z_m = s.z_m.map(|z| z + 0.02);
        }
        let gate = crate::rts::Gate::at(25.0);
        let start = CvParams { gate: Some(gate), ..Default::default() };
        let tuned = tune_noise(&start, &samples);
        assert!((tuned.params.r_m2 / r - 1.0).abs() < 0.3, "R {} vs {r}", tuned.params.r_m2);
    }
}
