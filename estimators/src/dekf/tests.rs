//! Whole-model checks: gradients against finite differences, equivalence of
//! the training and online paths, and learning on a synthetic problem.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

use super::*;
use crate::derivative::DerivativeFilterConfig;

fn meta(channels: usize) -> ModelMeta {
    ModelMeta {
        dt_s: 0.03,
        decimation: 3,
        tactile_rate_hz: 100.0,
        channels: (0..channels).map(|c| format!("ch{c}")).collect(),
        measurement: Measurement::Derivative,
        derivative_filter: DerivativeFilterConfig::default(),
        state_units: ["cm".into(), "cm/s".into()],
        p0_diag: [0.1, 0.1],
        training: serde_json::Value::Null,
        software_version: "test".into(),
    }
}

/// A synthetic sliding problem: the velocity follows a smooth periodic
/// profile of stick and slip; the measurements are noisy functions of it.
fn synthetic(len: usize, seed: u64) -> Sequence {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let noise = Normal::new(0.0, 0.1).unwrap();
    let (mut p, mut truth, mut meas, mut valid) = (0.0, Vec::new(), Vec::new(), Vec::new());
    for t in 0..len {
        let phase = t as f64 * 0.03 * std::f64::consts::TAU / 6.0 + seed as f64;
        let v = (phase.sin() - 0.6).max(0.0) * 1.5;
        p += v * 0.03;
        truth.push([p, v]);
        meas.extend([(2.0 * v + noise.sample(&mut rng)) as f32, (-v + noise.sample(&mut rng)) as f32]);
        valid.push(t % 17 != 5);
    }
    Sequence { measurements: meas, valid, truth }
}

#[test]
fn gradients_match_finite_differences_of_the_loss() {
    let mut model = DekfModel::new(meta(2), &mut ChaCha8Rng::seed_from_u64(5));
    // A non-trivial noise model.
    let o = model.layout.process_noise;
    model.params[o + 2] = 0.05;
    let data = vec![synthetic(40, 1), synthetic(40, 2)];
    let windows = [
        Window { sequence: 0, start: 3, mean0: [0.1, 0.2], position_shift: 0.0 },
        Window { sequence: 1, start: 10, mean0: [0.3, -0.1], position_shift: 1.5 },
        Window { sequence: 0, start: 20, mean0: [0.9, 0.4], position_shift: -0.7 },
    ];
    let length = 4;
    let g = batch_grad(&model, &data, &windows, length);
    let loss = |params: &[f32]| {
        let m = DekfModel { params: params.to_vec(), ..model.clone() };
        batch_grad(&m, &data, &windows, length).squared_error
    };
    let l = &model.layout;
    let mut candidates = vec![o, o + 2, o + 3, l.measurement_noise];
    for net in [&l.motion, &l.measurement, &l.feature] {
        for layer in [&net.layers[0], &net.layers[4], &net.layers[10]] {
            candidates.extend([layer.weight, layer.weight + 1, layer.bias]);
        }
    }
    let (mut checked, mut skipped) = (0, 0);
    for &i in &candidates {
        let fd = |eps: f32| {
            let mut up = model.params.clone();
            let mut down = model.params.clone();
            up[i] += eps;
            down[i] -= eps;
            (loss(&up) - loss(&down)) / (2.0 * f64::from(eps))
        };
        // Small steps make crossing a ReLU kink unlikely; two step sizes that
        // disagree mean one was crossed anyway.
        let (a, b) = (fd(3e-4), fd(1.5e-4));
        if (a - b).abs() > 0.01 * (a.abs() + b.abs()) + 1e-3 {
            skipped += 1;
            continue;
        }
        let analytic = f64::from(g.grad[i]);
        // 1e-3: the noise floor of differences of f32 network evaluations.
        assert!(
            (a - analytic).abs() < 0.01 * a.abs() + 1e-3,
            "parameter {i}: numeric {a}, analytic {analytic}"
        );
        checked += 1;
    }
    assert!(
        checked >= candidates.len() * 3 / 4,
        "checked {checked}, skipped {skipped} of {}",
        candidates.len()
    );
}

#[test]
fn the_online_filter_follows_the_training_path() {
    // With the truth set to the online filter's own states, the training
    // forward pass from the same initial state has zero error at every step:
    // both paths compute the same filter.
    let model = DekfModel::new(meta(2), &mut ChaCha8Rng::seed_from_u64(9));
    let mut seq = synthetic(30, 4);
    let mut tracker = DekfTracker::new(&model);
    for t in 1..seq.len() {
        let m = &seq.measurements[2 * t..2 * t + 2];
        let raw: Vec<f64> =
            if seq.valid[t] { m.iter().map(|v| f64::from(*v)).collect() } else { vec![f64::NAN; 2] };
        tracker.step(&raw);
        seq.truth[t] = tracker.state().0;
    }
    let data = vec![seq];
    let g = batch_grad(
        &model,
        &data,
        &[Window { sequence: 0, start: 0, mean0: [0.0, 0.0], position_shift: 0.0 }],
        29,
    );
    assert!(g.squared_error < 1e-8, "squared error {}", g.squared_error);
}

#[test]
fn training_learns_the_synthetic_slide() {
    let data: Vec<Sequence> = (0..6).map(|s| synthetic(400, s)).collect();
    let mut model = DekfModel::new(meta(2), &mut ChaCha8Rng::seed_from_u64(2));
    let cfg = TrainConfig {
        schedule: vec![Stage { length: 4, epochs: 3 }, Stage { length: 16, epochs: 3 }],
        batch_size: 16,
        learning_rate: 3e-3,
        ..TrainConfig::default()
    };
    let reports = train(&mut model, &data, &cfg, &mut |_| {});
    let first = &reports[0];
    let last = reports.last().unwrap();
    assert!(last.rmse[1] < 0.5 * first.rmse[1], "velocity RMSE {:?} -> {:?}", first.rmse, last.rmse);
    // Online on a held-out sequence: the velocity follows the truth.
    let test = synthetic(400, 99);
    let mut tracker = DekfTracker::new(&model);
    let mut se = 0.0;
    let mut base = 0.0;
    for t in 1..test.len() {
        let m = &test.measurements[2 * t..2 * t + 2];
        tracker.step(&[f64::from(m[0]), f64::from(m[1])]);
        let v = tracker.state().0[1];
        se += (v - test.truth[t][1]).powi(2);
        base += test.truth[t][1].powi(2);
    }
    assert!(se < 0.25 * base, "velocity error {se} vs zero-velocity baseline {base}");
}

/// The shards of a batch's gradient do not depend on the thread count, so
/// neither does the model (before the fix, `--threads 1` summed one shard of
/// 16 windows and `--threads 2` two of 8, and the models drifted apart).
#[test]
fn the_same_seed_gives_the_same_model_on_any_number_of_threads() {
    let data: Vec<Sequence> = (0..4).map(|s| synthetic(200, s)).collect();
    let trained = |threads: usize| {
        let mut model = DekfModel::new(meta(2), &mut ChaCha8Rng::seed_from_u64(3));
        let cfg = TrainConfig {
            schedule: vec![Stage { length: 4, epochs: 2 }, Stage { length: 8, epochs: 1 }],
            batch_size: 24,
            threads,
            ..TrainConfig::default()
        };
        train(&mut model, &data, &cfg, &mut |_| {});
        model.params
    };
    let one = trained(1);
    assert_eq!(one, trained(2), "1 and 2 threads");
    assert_eq!(one, trained(3), "1 and 3 threads");
}

/// Timing of a thesis-sized training (run in release: `cargo test --release -p
/// slidetrack-estimators thesis_sized -- --ignored --nocapture`).
#[test]
#[ignore = "timing aid"]
fn thesis_sized_training_time() {
    let data: Vec<Sequence> = (0..50)
        .map(|s| {
            let mut q = synthetic(1800, s);
            // six channels
            q.measurements =
                q.measurements.chunks(2).flat_map(|c| [c[0], c[1], c[0], c[1], c[0], c[1]]).collect();
            q
        })
        .collect();
    let mut model = DekfModel::new(meta(6), &mut ChaCha8Rng::seed_from_u64(2));
    for (batch, length) in [(32usize, 2usize), (32, 32), (128, 2), (128, 32)] {
        let cfg = TrainConfig {
            schedule: vec![Stage { length, epochs: 1 }],
            batch_size: batch,
            ..TrainConfig::default()
        };
        let t = std::time::Instant::now();
        train(&mut model, &data, &cfg, &mut |_| {});
        println!("batch {batch} length {length}: one epoch {:.2} s", t.elapsed().as_secs_f64());
    }
}

#[test]
fn nan_in_the_tactile_stream_is_skipped_never_propagated() {
    let model = DekfModel::new(meta(2), &mut ChaCha8Rng::seed_from_u64(4));
    let mut tracker = DekfTracker::new(&model);
    let mut corrected = 0;
    let mut predicted_only = 0;
    for k in 0..300 {
        let t = k as f64 * 0.01;
        let v = if (100..130).contains(&k) { [f64::NAN, 5.0] } else { [100.0 * t, -50.0 * t] };
        if let Some(out) = tracker.on_scan(t, &v) {
            assert!(
                out.mean.iter().all(|x| x.is_finite()) && out.cov.iter().flatten().all(|x| x.is_finite())
            );
            assert!(
                out.measurement.iter().all(|x| x.is_finite()),
                "the derivative filter predicts through NaN"
            );
            if out.corrected { corrected += 1 } else { predicted_only += 1 }
        }
    }
    assert!(corrected > 50 && predicted_only >= 1);
    // A NaN the feature network would read: prediction only.
    let mut raw = DekfModel::new(
        ModelMeta { measurement: Measurement::Raw, ..meta(2) },
        &mut ChaCha8Rng::seed_from_u64(4),
    );
    raw.meta.decimation = 1;
    let mut tracker = DekfTracker::new(&raw);
    tracker.on_scan(0.0, &[1.0, 2.0]);
    let out = tracker.on_scan(0.03, &[f64::NAN, 2.0]).unwrap();
    assert!(!out.corrected && out.mean.iter().all(|x| x.is_finite()));
}
