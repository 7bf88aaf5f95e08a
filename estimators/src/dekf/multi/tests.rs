//! Whole-model checks of the planar dEKF: the loss gradient against finite
//! differences, the online filter against the training path, the filter
//! with silent networks against the constant-velocity model, and learning
//! on a synthetic planar slip.

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

use crate::dekf::{
    DekfModel, DekfTracker, Measurement, ModelMeta, Sequence, Stage, StateKind, TrainConfig, Window,
    batch_grad, train,
};
use crate::derivative::DerivativeFilterConfig;

const CHANNELS: usize = 4;

fn meta() -> ModelMeta {
    ModelMeta {
        dt_s: 0.05,
        decimation: 1,
        tactile_rate_hz: 20.0,
        channels: (0..CHANNELS).map(|c| format!("ch{c}")).collect(),
        measurement: Measurement::Derivative,
        derivative_filter: DerivativeFilterConfig::default(),
        state: StateKind::Planar,
        state_units: StateKind::Planar.units(),
        p0_diag: StateKind::Planar.default_p0_diag(),
        training: serde_json::Value::Null,
        software_version: "test".into(),
    }
}

/// A synthetic planar slip: each degree of freedom moves in smooth bursts
/// (its own phase); four channels read noisy mixtures of the rates.
fn synthetic(len: usize, seed: u64) -> Sequence {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let noise = Normal::new(0.0, 0.1).expect("valid");
    let (mut p, mut truth, mut meas, mut valid) = ([0.0f64; 3], Vec::new(), Vec::new(), Vec::new());
    for t in 0..len {
        let v: [f64; 3] = std::array::from_fn(|i| {
            let phase = t as f64 * 0.05 * std::f64::consts::TAU / (4.0 + i as f64) + seed as f64 + i as f64;
            (phase.sin() - 0.5).max(0.0) * [1.5, -1.0, 3.0][i]
        });
        for i in 0..3 {
            p[i] += v[i] * 0.05;
        }
        truth.extend(p);
        truth.extend(v);
        let mut n = || noise.sample(&mut rng);
        meas.extend([
            (2.0 * v[0] + n()) as f32,
            (-v[1] + n()) as f32,
            (0.5 * v[2] + n()) as f32,
            (v[0] + v[1] - 0.2 * v[2] + n()) as f32,
        ]);
        valid.push(t % 13 != 4);
    }
    Sequence { measurements: meas, valid, truth, dim: 6 }
}

#[test]
fn a_planar_model_has_three_outputs_per_network_and_full_noise_factors() {
    let model = DekfModel::new(meta(), &mut ChaCha8Rng::seed_from_u64(1));
    let l = &model.layout;
    assert_eq!(l.entry("motion.encoder.linear.weight").map(|e| e.shape.clone()), Some(vec![64, 6]));
    assert_eq!(l.entry("motion.shared.out.weight").map(|e| e.shape.clone()), Some(vec![3, 64]));
    assert_eq!(l.entry("feature.shared.out.weight").map(|e| e.shape.clone()), Some(vec![3, 64]));
    assert_eq!(l.entry("process_noise.cholesky").map(|e| e.shape.clone()), Some(vec![6, 6]));
    assert_eq!(l.entry("measurement_noise.cholesky").map(|e| e.shape.clone()), Some(vec![3, 3]));
    let q = model.process_noise_matrix();
    assert!((q[(0, 0)] - 0.01).abs() < 1e-7 && (q[(5, 5)] - 0.09).abs() < 1e-7 && q[(1, 0)] == 0.0);
    assert_eq!(model.measurement_noise_matrix(), nalgebra::DMatrix::identity(3, 3));
    // 15 upper elements of L_Q and 3 of L_R are not trained.
    let mask = l.trainable_mask();
    let untrained = |o: usize, k: usize| (0..k * k).filter(|i| !mask[o + i]).count();
    assert_eq!(untrained(l.process_noise, 6), 15);
    assert_eq!(untrained(l.measurement_noise, 3), 3);
}

/// The planar loss gradient against central differences, on two
/// architectures (the thesis's ReLU and a smooth one), for two random
/// elements of every trainable tensor.
#[test]
fn planar_gradients_match_finite_differences_of_the_loss() {
    let data = vec![synthetic(40, 1), synthetic(40, 2)];
    let archs = crate::dekf::mlp::tests::architectures();
    for arch in [archs[0], archs[1]] {
        let (mut checked, mut skipped) = (0usize, 0usize);
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let mut model = DekfModel::with_architecture(meta(), &arch, &mut rng);
        // Non-trivial noise models: off-diagonal Cholesky elements.
        let (q, r) = (model.layout.process_noise, model.layout.measurement_noise);
        model.params[q + 6 * 4 + 1] = 0.05;
        model.params[r + 3 * 2] = 0.3;
        let mut window = |shift: f64| Window {
            sequence: rng.random_range(0..2),
            start: rng.random_range(0..30),
            mean0: (0..6).map(|_| rng.random_range(-1.0..1.0)).collect(),
            position_shift: vec![shift, -shift, 0.5 * shift],
        };
        let windows = [window(0.0), window(1.5), window(-0.7)];
        let length = 4;
        let g = batch_grad(&model, &data, &windows, length);
        let loss = |params: &[f32]| {
            let m = DekfModel { params: params.to_vec(), ..model.clone() };
            batch_grad(&m, &data, &windows, length).squared_error
        };
        let mask = model.layout.trainable_mask();
        for e in model.layout.entries.iter().filter(|e| e.trainable) {
            let candidates: Vec<usize> = e.range().filter(|&i| mask[i]).collect();
            for _ in 0..2 {
                let i = candidates[rng.random_range(0..candidates.len())];
                let fd = |eps: f32| {
                    let (mut up, mut down) = (model.params.clone(), model.params.clone());
                    up[i] += eps;
                    down[i] -= eps;
                    (loss(&up) - loss(&down)) / (2.0 * f64::from(eps))
                };
                let eps = if arch.activation.has_curvature() { 3e-3 } else { 3e-4 };
                let (a, b) = (fd(eps), fd(eps / 2.0));
                let noise = 4e-3;
                if (a - b).abs() > 0.004 * (a.abs() + b.abs()) + noise / 2.0 {
                    skipped += 1;
                    continue;
                }
                let analytic = f64::from(g.grad[i]);
                assert!(
                    (a - analytic).abs() < 0.01 * a.abs() + noise,
                    "{arch:?} {} [{}]: numeric {a}, analytic {analytic}",
                    e.name,
                    i - e.offset
                );
                checked += 1;
            }
        }
        assert!(skipped * 10 <= checked + skipped, "{arch:?}: skipped {skipped} of {}", checked + skipped);
    }
}

#[test]
fn the_planar_online_filter_follows_the_training_path() {
    let model = DekfModel::new(meta(), &mut ChaCha8Rng::seed_from_u64(9));
    let mut seq = synthetic(30, 4);
    let mut tracker = DekfTracker::new(&model);
    for t in 1..seq.len() {
        let m = &seq.measurements[CHANNELS * t..CHANNELS * (t + 1)];
        let raw: Vec<f64> =
            if seq.valid[t] { m.iter().map(|v| f64::from(*v)).collect() } else { vec![f64::NAN; CHANNELS] };
        tracker.step(&raw);
        seq.truth[6 * t..6 * t + 6].copy_from_slice(&tracker.state().0);
    }
    let w = Window { sequence: 0, start: 0, mean0: vec![0.0; 6], position_shift: vec![0.0; 3] };
    let g = batch_grad(&model, &[seq], &[w], 29);
    assert!(g.squared_error < 1e-8, "squared error {}", g.squared_error);
}

/// With every network silent (output 0, Jacobian 0) the planar filter is the
/// constant-velocity model without correction: the mean keeps its velocity,
/// and the covariance follows `F P F^T + Q` with `F = [[I, dt I], [0, I]]`.
#[test]
fn a_planar_dekf_with_silent_networks_is_the_constant_velocity_model() {
    let mut model = DekfModel::new(meta(), &mut ChaCha8Rng::seed_from_u64(3));
    let l = model.layout.clone();
    for net in [&l.motion, &l.measurement, &l.feature] {
        let out = *net.out();
        model.params[out.weight..out.weight + out.out * out.inp].iter_mut().for_each(|w| *w = 0.0);
        model.params[out.bias..out.bias + out.out].iter_mut().for_each(|w| *w = 0.0);
    }
    model.params[l.process_noise + 6 * 3 + 1] = 0.02;
    let q = model.process_noise_matrix();
    let mut f = nalgebra::DMatrix::<f64>::identity(6, 6);
    for i in 0..3 {
        f[(i, 3 + i)] = 0.05;
    }
    let mut p = nalgebra::DMatrix::from_diagonal_element(6, 6, 0.1);
    let mut tracker = DekfTracker::new(&model);
    for _ in 0..20 {
        tracker.step(&[0.3, -0.1, 0.2, 0.0]);
        p = &f * p * f.transpose() + &q;
        let (mean, cov) = tracker.state();
        assert!(mean.iter().all(|m| *m == 0.0), "{mean:?}");
        for (got, want) in cov.iter().zip(p.transpose().iter()) {
            assert!((got - want).abs() < 1e-9 * (1.0 + want.abs()), "{got} vs {want}");
        }
    }
}

#[test]
fn training_learns_the_synthetic_planar_slip() {
    let data: Vec<Sequence> = (0..6).map(|s| synthetic(300, s)).collect();
    let mut model = DekfModel::new(meta(), &mut ChaCha8Rng::seed_from_u64(2));
    let cfg = TrainConfig {
        schedule: vec![Stage { length: 4, epochs: 8 }, Stage { length: 16, epochs: 8 }],
        batch_size: 16,
        learning_rate: 3e-3,
        ..TrainConfig::default()
    };
    let reports = train(&mut model, &data, &cfg, &mut |_| {});
    let (first, last) = (&reports[0], &reports[reports.len() - 1]);
    assert!(last.rmse[1] < 0.5 * first.rmse[1], "velocity RMSE {:?} -> {:?}", first.rmse, last.rmse);
    // Online on a held-out sequence: every rate follows the truth better
    // than predicting no motion.
    let test = synthetic(300, 99);
    let mut tracker = DekfTracker::new(&model);
    let (mut se, mut base) = ([0.0; 3], [0.0; 3]);
    for t in 1..test.len() {
        let m = &test.measurements[CHANNELS * t..CHANNELS * (t + 1)];
        tracker.step(&m.iter().map(|v| f64::from(*v)).collect::<Vec<_>>());
        let v = &tracker.state().0[3..];
        for i in 0..3 {
            se[i] += (v[i] - test.truth_at(t)[3 + i]).powi(2);
            base[i] += test.truth_at(t)[3 + i].powi(2);
        }
    }
    for i in 0..3 {
        assert!(se[i] < 0.35 * base[i], "rate {i}: error {} vs zero-rate baseline {}", se[i], base[i]);
    }
}
