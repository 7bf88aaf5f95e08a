//! The smoother against closed forms: the batch least-squares estimate of a
//! static state, and the whole trajectory solved as one Gaussian linear
//! system in information form.

use std::ops::AddAssign;

use nalgebra::{DMatrix, DVector, SMatrix, SVector};

use super::*;

/// A small deterministic generator (splitmix64), uniform in `[-1, 1)`.
struct Uniform(u64);

impl Uniform {
    fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        (z >> 11) as f64 / (1u64 << 52) as f64 - 1.0
    }

    fn matrix<const R: usize, const C: usize>(&mut self) -> SMatrix<f64, R, C> {
        SMatrix::from_fn(|_, _| self.next())
    }

    /// A random symmetric positive definite matrix, eigenvalues >= `floor`.
    fn spd<const N: usize>(&mut self, floor: f64) -> SMatrix<f64, N, N> {
        let a = self.matrix::<N, N>();
        a * a.transpose() + SMatrix::identity() * floor
    }
}

/// A random linear-Gaussian problem: initial belief, steps, measurements
/// (some missing).
struct Problem<const N: usize, const M: usize> {
    initial: Gaussian<N>,
    transitions: Vec<Transition<N>>,
    measurements: Vec<Option<Measurement<N, M>>>,
}

fn random_problem<const N: usize, const M: usize>(seed: u64, steps: usize) -> Problem<N, M> {
    let mut rng = Uniform(seed);
    let initial = Gaussian::new(rng.matrix::<N, 1>(), rng.spd::<N>(0.5));
    let mut transitions = Vec::new();
    let mut measurements = Vec::new();
    for k in 0..steps {
        let F = SMatrix::<f64, N, N>::identity() + rng.matrix::<N, N>() * 0.3;
        transitions.push(Transition { F, Q: rng.spd::<N>(0.05) * 0.2 });
        let measured = k % 4 != 2 && rng.next() > -0.6;
        measurements.push(measured.then(|| Measurement {
            z: rng.matrix::<M, 1>() * 3.0,
            H: rng.matrix::<M, N>(),
            R: rng.spd::<M>(0.1),
        }));
    }
    Problem { initial, transitions, measurements }
}

fn run<const N: usize, const M: usize>(p: &Problem<N, M>) -> (Vec<FilteredStep<N>>, Vec<Gaussian<N>>) {
    let mut filter = ForwardFilter::new(p.initial);
    for (t, m) in p.transitions.iter().zip(&p.measurements) {
        filter.step(*t, m.as_ref()).unwrap();
    }
    let steps = filter.into_steps();
    let smoothed = smooth(&steps).unwrap();
    (steps, smoothed)
}

/// The reference, written differently: the states `x_-1 (the initial
/// belief's variable), x_0 .. x_T-1` as one vector, the negative log
/// posterior as a quadratic form `x^T L x - 2 x^T e`, solved densely. The
/// smoothed means are the blocks of `L^-1 e`, the covariances the diagonal
/// blocks of `L^-1`.
fn batch_information_form<const N: usize, const M: usize>(p: &Problem<N, M>) -> Vec<Gaussian<N>> {
    let n = N * (p.transitions.len() + 1);
    let mut L = DMatrix::<f64>::zeros(n, n);
    let mut e = DVector::<f64>::zeros(n);
    let inv = |a: &DMatrix<f64>| a.clone().try_inverse().unwrap();
    let dm = |a: &dyn Fn(usize, usize) -> f64, r: usize, c: usize| DMatrix::from_fn(r, c, a);
    let P0 = dm(&|i, j| p.initial.cov[(i, j)], N, N);
    let m0 = DVector::from_iterator(N, p.initial.mean.iter().copied());
    let P0_inv = inv(&P0);
    L.view_mut((0, 0), (N, N)).add_assign(&P0_inv);
    e.rows_mut(0, N).add_assign(&(&P0_inv * &m0));
    for (k, (t, m)) in p.transitions.iter().zip(&p.measurements).enumerate() {
        let (prev, cur) = (k * N, (k + 1) * N);
        // (x_k - F x_k-1)^T Q^-1 (x_k - F x_k-1) = [x_k-1; x_k]^T A^T Q^-1 A [..], A = [-F, I].
        let mut A = DMatrix::<f64>::zeros(N, 2 * N);
        A.view_mut((0, 0), (N, N)).copy_from(&dm(&|i, j| -t.F[(i, j)], N, N));
        A.view_mut((0, N), (N, N)).fill_with_identity();
        let Q_inv = inv(&dm(&|i, j| t.Q[(i, j)], N, N));
        let block = A.transpose() * Q_inv * &A;
        L.view_mut((prev, prev), (2 * N, 2 * N)).add_assign(&block);
        if let Some(m) = m {
            let H = dm(&|i, j| m.H[(i, j)], M, N);
            let R_inv = inv(&dm(&|i, j| m.R[(i, j)], M, M));
            let z = DVector::from_iterator(M, m.z.iter().copied());
            L.view_mut((cur, cur), (N, N)).add_assign(&(H.transpose() * &R_inv * &H));
            e.rows_mut(cur, N).add_assign(&(H.transpose() * &R_inv * z));
        }
    }
    let cov = inv(&L);
    let mean = &cov * e;
    (1..=p.transitions.len())
        .map(|k| {
            let at = k * N;
            Gaussian::new(
                SVector::from_fn(|i, _| mean[at + i]),
                SMatrix::from_fn(|i, j| cov[(at + i, at + j)]),
            )
        })
        .collect()
}

fn max_abs_diff<const N: usize>(a: &Gaussian<N>, b: &Gaussian<N>) -> f64 {
    let dm = (a.mean - b.mean).abs().max();
    let dc = (a.cov - b.cov).abs().max();
    dm.max(dc)
}

#[test]
fn the_smoother_equals_the_batch_solution_of_the_whole_trajectory_on_random_problems() {
    for seed in 0..20 {
        let p = random_problem::<3, 2>(seed, 40);
        let (_, smoothed) = run(&p);
        let reference = batch_information_form(&p);
        for (k, (s, r)) in smoothed.iter().zip(&reference).enumerate() {
            let d = max_abs_diff(s, r);
            assert!(d < 1e-9, "seed {seed} step {k}: differs by {d:e}\n{s:?}\n{r:?}");
        }
    }
    for seed in 100..110 {
        let p = random_problem::<2, 1>(seed, 60);
        let (_, smoothed) = run(&p);
        for (s, r) in smoothed.iter().zip(&batch_information_form(&p)) {
            assert!(max_abs_diff(s, r) < 1e-9);
        }
    }
}

#[test]
fn the_last_smoothed_belief_is_the_last_filtered_one_and_smoothing_never_adds_uncertainty() {
    let p = random_problem::<3, 2>(7, 30);
    let (steps, smoothed) = run(&p);
    assert_eq!(smoothed.last(), steps.last().map(|s| &s.posterior));
    for (s, f) in smoothed.iter().zip(&steps) {
        let gain = f.posterior.cov - s.cov;
        assert!(gain.symmetric_eigenvalues().min() > -1e-12, "P_filtered - P_smoothed is PSD");
    }
}

#[test]
fn a_static_fully_observed_state_is_smoothed_to_the_batch_least_squares_estimate() {
    // F = I, Q = 0, H = I: every smoothed belief equals the weighted least
    // squares of the prior and all measurements,
    // P = (P0^-1 + sum R_k^-1)^-1, x = P (P0^-1 m0 + sum R_k^-1 z_k).
    let mut rng = Uniform(42);
    let initial = Gaussian::new(rng.matrix::<2, 1>(), rng.spd::<2>(1.0) * 4.0);
    let mut filter = ForwardFilter::new(initial);
    let mut info = initial.cov.try_inverse().unwrap();
    let mut weighted = info * initial.mean;
    for k in 0..25 {
        let m = Measurement {
            z: SVector::<f64, 2>::new(1.5, -0.5) + rng.matrix::<2, 1>() * 0.2,
            H: SMatrix::<f64, 2, 2>::identity(),
            R: rng.spd::<2>(0.1),
        };
        let measured = k % 3 != 1;
        if measured {
            let R_inv = m.R.try_inverse().unwrap();
            info += R_inv;
            weighted += R_inv * m.z;
        }
        filter.step(Transition::identity(), measured.then_some(&m)).unwrap();
    }
    let P = info.try_inverse().unwrap();
    let batch = Gaussian::new(P * weighted, P);
    let smoothed = smooth(filter.steps()).unwrap();
    for (k, s) in smoothed.iter().enumerate() {
        let d = max_abs_diff(s, &batch);
        assert!(d < 1e-9, "step {k}: {d:e}");
    }
}

#[test]
fn a_gated_outlier_is_smoothed_as_if_it_were_missing() {
    let mut p = random_problem::<2, 1>(3, 30);
    for m in p.measurements.iter_mut().flatten() {
        m.H = SMatrix::<f64, 1, 2>::new(1.0, 0.0);
        m.R = SMatrix::<f64, 1, 1>::new(0.01);
    }
    let good = |k: usize| p.measurements[k].is_some();
    let k_out = (10..30).find(|&k| good(k)).unwrap();
    // The random measurements do not follow the model: a wide gate that only
    // the 1000-unit outlier exceeds.
    let mut filter = ForwardFilter::new(p.initial).with_gate(Some(Gate::at(1e4)));
    let mut without = ForwardFilter::new(p.initial);
    for (k, (t, m)) in p.transitions.iter().zip(&p.measurements).enumerate() {
        let outlier = m.map(|m| Measurement { z: m.z.add_scalar(1e3), ..m });
        let used = if k == k_out { outlier.as_ref() } else { m.as_ref() };
        let step = filter.step(*t, used).unwrap();
        if k == k_out {
            assert!(
                matches!(step.measurement, MeasurementUse::Rejected { mahalanobis2 } if mahalanobis2 > 1e3)
            );
        }
        without.step(*t, if k == k_out { None } else { m.as_ref() }).unwrap();
    }
    let rejected = filter.steps().iter().filter(|s| matches!(s.measurement, MeasurementUse::Rejected { .. }));
    assert_eq!(rejected.count(), 1);
    let gated = smooth(filter.steps()).unwrap();
    let reference = smooth(without.steps()).unwrap();
    assert_eq!(gated, reference);
}

/// A constant-velocity filter at rest on 0 whose measured position jumps to
/// 5 cm (a fall) and stays there: a gate alone rejects every later position
/// and the filter stays at 0 for good; re-acquiring after 3 rejections in a
/// row, it accepts the fourth and every one after. A single outlier is still
/// rejected. (Opening the gate for the fourth position only, the filter
/// stuttered: 10 of the next 14 positions rejected.)
#[test]
fn a_gate_that_reacquires_follows_a_jump_a_gate_alone_locks_out_of() {
    let dt = 1.0 / 30.0;
    let t = Transition {
        F: SMatrix::<f64, 2, 2>::new(1.0, dt, 0.0, 1.0),
        Q: SMatrix::<f64, 2, 2>::new(1e-8 * dt, 0.0, 0.0, 1e-4 * dt),
    };
    let initial =
        Gaussian::new(SVector::<f64, 2>::zeros(), SMatrix::<f64, 2, 2>::new(2.5e-7, 0.0, 0.0, 1e-4));
    let at = |z: f64| Measurement {
        z: SVector::<f64, 1>::new(z),
        H: SMatrix::<f64, 1, 2>::new(1.0, 0.0),
        R: SMatrix::<f64, 1, 1>::new(2.5e-7),
    };
    // 1 s at 0 with one 2 cm outlier at 0.5 s, then 1 s at 5 cm.
    let z = |k: usize| match k {
        15 => 0.02,
        k if k < 30 => 0.0,
        _ => 0.05,
    };
    let run = |gate: Gate| {
        let mut filter = ForwardFilter::new(initial).with_gate(Some(gate));
        for k in 0..60 {
            filter.step(t, Some(&at(z(k)))).unwrap();
        }
        let rejected: Vec<usize> = (0..60)
            .filter(|&k| matches!(filter.steps()[k].measurement, MeasurementUse::Rejected { .. }))
            .collect();
        (filter.steps()[59].posterior.mean[0], rejected)
    };
    let (locked, rejected) = run(Gate::at(25.0));
    assert!(locked.abs() < 1e-3, "the gate alone ends at {locked} m");
    assert_eq!(rejected, [[15].as_slice(), &(30..60).collect::<Vec<_>>()].concat());
    let (followed, rejected) = run(Gate { max_mahalanobis2: 25.0, reacquire_after: Some(3) });
    assert!((followed - 0.05).abs() < 1e-3, "re-acquiring, it ends at {followed} m");
    assert_eq!(rejected[0], 15, "the lone outlier is rejected");
    assert_eq!(rejected, [15, 30, 31, 32], "rejected: the outlier and the first three after the jump");
}

#[test]
fn bad_input_is_an_error_and_leaves_the_filter_unchanged() {
    let initial = Gaussian::new(SVector::<f64, 1>::zeros(), SMatrix::<f64, 1, 1>::identity());
    let mut filter = ForwardFilter::new(initial);
    let nan = Measurement {
        z: SVector::<f64, 1>::new(f64::NAN),
        H: SMatrix::<f64, 1, 1>::identity(),
        R: SMatrix::<f64, 1, 1>::identity(),
    };
    assert_eq!(
        filter.step(Transition::identity(), Some(&nan)).unwrap_err(),
        EstimatorError::NonFiniteMeasurement
    );
    let singular = Measurement { z: SVector::<f64, 1>::zeros(), H: SMatrix::zeros(), R: SMatrix::zeros() };
    assert_eq!(
        filter.step(Transition::identity(), Some(&singular)).unwrap_err(),
        EstimatorError::SingularInnovation
    );
    assert!(filter.steps().is_empty());
    assert_eq!(filter.belief(), &initial);
    // A prior that cannot be inverted: zero covariance, no process noise.
    let certain = Gaussian::new(SVector::<f64, 1>::zeros(), SMatrix::<f64, 1, 1>::zeros());
    let mut filter = ForwardFilter::new(certain);
    filter.step::<1>(Transition::identity(), None).unwrap();
    filter.step::<1>(Transition::identity(), None).unwrap();
    assert_eq!(smooth(filter.steps()).unwrap_err(), EstimatorError::SingularPrior { step: 1 });
    assert!(smooth::<2>(&[]).unwrap().is_empty());
}
