//! Whole-model checks: gradients against finite differences, equivalence of
//! the training and online paths, and learning on a synthetic problem.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

use super::*;
use crate::dekf::params::{Layer, LinearAt};
use crate::derivative::DerivativeFilterConfig;

fn meta(channels: usize) -> ModelMeta {
    ModelMeta {
        dt_s: 0.03,
        decimation: 3,
        tactile_rate_hz: 100.0,
        channels: (0..channels).map(|c| format!("ch{c}")).collect(),
        measurement: Measurement::Derivative,
        derivative_filter: DerivativeFilterConfig::default(),
        state: StateKind::Sliding,
        state_units: vec!["cm".into(), "cm/s".into()],
        p0_diag: vec![0.1, 0.1],
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
    Sequence::sliding(meas, valid, &truth)
}

/// The model's loss gradient (every network, both noise models) against
/// central differences, for every architecture of the network tests: two
/// random elements of every trainable tensor, random initial states and
/// window starts, parameters from two seeds. Where two step sizes disagree a
/// ReLU kink was crossed: those candidates are counted and may be at most
/// 5 % of all.
#[test]
fn gradients_match_finite_differences_of_the_loss() {
    use rand::RngExt;
    let data = vec![synthetic(40, 1), synthetic(40, 2)];
    for arch in crate::dekf::mlp::tests::architectures() {
        let (mut checked, mut skipped, mut nonzero) = (0usize, 0usize, 0usize);
        for seed in [5u64, 6] {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            let mut model = DekfModel::with_architecture(meta(2), &arch, &mut rng);
            // A non-trivial noise model.
            let o = model.layout.process_noise;
            model.params[o + 2] = 0.05;
            let mut window = |position_shift: f64| Window {
                sequence: rng.random_range(0..2),
                start: rng.random_range(0..30),
                mean0: vec![rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0)],
                position_shift: vec![position_shift],
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
                        let mut up = model.params.clone();
                        let mut down = model.params.clone();
                        up[i] += eps;
                        down[i] -= eps;
                        (loss(&up) - loss(&down)) / (2.0 * f64::from(eps))
                    };
                    // ReLU: small steps make crossing a kink unlikely, and
                    // two step sizes that disagree mean one was crossed: then
                    // four times smaller ones (with four times the f32 noise)
                    // are tried before the candidate is skipped. Smooth:
                    // larger steps, less noise.
                    let mut eps = if arch.activation.has_curvature() { 3e-3 } else { 3e-4 };
                    let mut noise = 2e-3;
                    let (mut a, mut b) = (fd(eps), fd(eps / 2.0));
                    let kink = |a: f64, b: f64, noise: f64| {
                        (a - b).abs() > 0.004 * (a.abs() + b.abs()) + noise / 2.0
                    };
                    if kink(a, b, noise) {
                        (eps, noise) = (eps / 4.0, noise * 4.0);
                        (a, b) = (fd(eps), fd(eps / 2.0));
                    }
                    if kink(a, b, noise) {
                        skipped += 1;
                        continue;
                    }
                    let analytic = f64::from(g.grad[i]);
                    // `noise`: the floor of differences of f32 network evaluations.
                    assert!(
                        (a - analytic).abs() < 0.01 * a.abs() + noise,
                        "{arch:?} seed {seed} {} [{}]: numeric {a}, analytic {analytic} (step {eps})",
                        e.name,
                        i - e.offset
                    );
                    checked += 1;
                    nonzero += usize::from(analytic.abs() > 1e-2);
                }
            }
        }
        let total = checked + skipped;
        println!("{arch:?}: {checked} checked, {skipped} skipped at kinks, {nonzero} above 1e-2");
        assert!(skipped * 20 <= total, "{arch:?}: skipped {skipped} of {total}");
        assert!(nonzero * 3 >= checked, "{arch:?}: only {nonzero} of {checked} gradients above 1e-2");
    }
}

/// The closed-form constant-velocity EKF, written here from the textbook
/// and not through `ekf::predict`/`correct`: `F = [[1, dt], [0, 1]]`, a
/// linear measurement `z = h . x + offset` with noise `R`, the standard-form
/// covariance update `P = (I - K h) P-`. Returns the means after each step.
fn constant_velocity_ekf(
    mut x: [f64; 2],
    mut p: [[f64; 2]; 2],
    dt: f64,
    q: [[f64; 2]; 2],
    r: f64,
    measurement: Option<([f64; 2], f64)>,
    zs: &[f64],
) -> Vec<([f64; 2], [[f64; 2]; 2])> {
    let mut out = Vec::new();
    for &z in zs {
        // x- = F x, P- = F P F^T + Q, written out.
        x = [x[0] + dt * x[1], x[1]];
        let p00 = p[0][0] + dt * (p[1][0] + p[0][1]) + dt * dt * p[1][1] + q[0][0];
        let p01 = p[0][1] + dt * p[1][1] + q[0][1];
        let p10 = p[1][0] + dt * p[1][1] + q[1][0];
        let p11 = p[1][1] + q[1][1];
        p = [[p00, p01], [p10, p11]];
        if let Some((h, offset)) = measurement {
            let ph = [p[0][0] * h[0] + p[0][1] * h[1], p[1][0] * h[0] + p[1][1] * h[1]];
            let s = h[0] * ph[0] + h[1] * ph[1] + r;
            let k = [ph[0] / s, ph[1] / s];
            let innovation = z - (h[0] * x[0] + h[1] * x[1] + offset);
            x = [x[0] + k[0] * innovation, x[1] + k[1] * innovation];
            let hp = [h[0] * p[0][0] + h[1] * p[1][0], h[0] * p[0][1] + h[1] * p[1][1]];
            p = [
                [p[0][0] - k[0] * hp[0], p[0][1] - k[0] * hp[1]],
                [p[1][0] - k[1] * hp[0], p[1][1] - k[1] * hp[1]],
            ];
        }
        out.push((x, p));
    }
    out
}

/// Sets every parameter of `net`'s output layer to zero: the network then
/// outputs 0 with a zero Jacobian, whatever its inside.
fn silence(model: &mut DekfModel, net: &crate::dekf::params::NetAt) {
    let out = *net.out();
    model.params[out.weight..out.weight + out.inp].iter_mut().for_each(|w| *w = 0.0);
    model.params[out.bias] = 0.0;
}

/// Makes the ReLU network `net` exactly `y = sum_i c_i (x_i + b_i)` on its
/// first two inputs: units `relu(+-(x_i + b_i))` pass unchanged through
/// residual blocks with zero weights (their inputs are not negative) and an
/// identity `shared.linear`; the output takes their differences. Exact
/// everywhere but at `x_i = -b_i`.
fn make_linear(model: &mut DekfModel, net: &crate::dekf::params::NetAt, c: [f32; 2], b: [f32; 2]) {
    let p = &mut model.params;
    for l in net.linears() {
        p[l.weight..l.weight + l.out * l.inp].iter_mut().for_each(|w| *w = 0.0);
        p[l.bias..l.bias + l.out].iter_mut().for_each(|w| *w = 0.0);
    }
    // The linear layers outside residual blocks: encoder.linear, shared.linear, shared.out.
    let plain: Vec<LinearAt> = net
        .layers
        .iter()
        .filter_map(|layer| if let Layer::Linear(l) = layer { Some(*l) } else { None })
        .collect();
    let [enc, shared, out] = plain[..] else { panic!("three plain linear layers: {plain:?}") };
    let w = enc.out;
    for i in 0..2 {
        for (unit, sign) in [(2 * i, 1.0), (2 * i + 1, -1.0)] {
            // Column-major [out, in]: element (unit, input i).
            p[enc.weight + i * w + unit] = sign;
            p[enc.bias + unit] = sign * b[i];
            p[shared.weight + unit * w + unit] = 1.0;
            p[out.weight + unit] = sign * c[i];
        }
    }
}

/// A dEKF whose networks output zero is the constant-velocity model (with
/// no correction: `H = 0`), on every architecture; with a motion network
/// that outputs zero and linear measurement and feature networks (ReLU
/// networks can be exactly linear) it is the constant-velocity EKF with a
/// linear measurement. Both the online filter and the training path are
/// checked against the closed form written above.
#[test]
fn a_dekf_whose_networks_output_zero_is_the_constant_velocity_ekf() {
    let seq = synthetic(80, 3);
    let zs: Vec<f64> = (1..seq.len()).map(|t| f64::from(seq.measurements[2 * t])).collect();
    for arch in crate::dekf::mlp::tests::architectures() {
        let mut model = DekfModel::with_architecture(meta(2), &arch, &mut ChaCha8Rng::seed_from_u64(8));
        let o = model.layout.process_noise;
        model.params[o..o + 4].copy_from_slice(&[0.2, 0.0, 0.05, 0.4]);
        model.params[model.layout.measurement_noise] = 0.7;
        let l = model.layout.clone();
        silence(&mut model, &l.motion);
        let mut zero = model.clone();
        silence(&mut zero, &l.measurement);
        let mut cases = vec![(zero, None)];
        if !arch.activation.has_curvature() {
            // zhat = 0.125 (p - 1.5) + 0.5 (v + 0.25) and NN3 = m0 + 0.5:
            // the innovation of z = m0 against h . x + offset.
            let mut linear = model.clone();
            make_linear(&mut linear, &l.measurement, [0.125, 0.5], [-1.5, 0.25]);
            make_linear(&mut linear, &l.feature, [1.0, 0.0], [0.5, 0.0]);
            cases.push((linear, Some(([0.125, 0.5], 0.125 * -1.5 + 0.5 * 0.25 - 0.5))));
        }
        for (model, measurement) in cases {
            let (q, r, p0) = (model.process_noise(), model.measurement_noise(), model.meta.p0_diag.clone());
            let p0 = [[p0[0], 0.0], [0.0, p0[1]]];
            // Online, from mu0 = 0.
            let expected = constant_velocity_ekf([0.0; 2], p0, 0.03, q, r, measurement, &zs);
            let mut tracker = DekfTracker::new(&model);
            for (t, (x, p)) in expected.iter().enumerate() {
                let m = &seq.measurements[2 * (t + 1)..2 * (t + 2)];
                tracker.step(&[f64::from(m[0]), f64::from(m[1])]);
                let (mean, cov) = tracker.state();
                for (got, want) in mean.iter().chain(cov.iter()).zip(x.iter().chain(p.iter().flatten())) {
                    assert!(
                        (got - want).abs() < 1e-5 * (1.0 + want.abs()),
                        "{arch:?} step {t}: {got} vs {want}"
                    );
                }
            }
            // Training path, from another state: the closed form is its truth.
            let mean0 = [0.8, -0.6];
            let expected = constant_velocity_ekf(mean0, p0, 0.03, q, r, measurement, &zs[9..]);
            let mut s = seq.clone();
            for (k, (x, _)) in expected.iter().enumerate() {
                s.truth[2 * (10 + k)..2 * (11 + k)].copy_from_slice(x);
                s.valid[10 + k] = true;
            }
            let w = Window { sequence: 0, start: 9, mean0: mean0.to_vec(), position_shift: vec![0.0] };
            let g = batch_grad(&model, &[s], &[w], expected.len());
            assert!(g.squared_error < 1e-8, "{arch:?}: squared error {} against the CV-EKF", g.squared_error);
        }
    }
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
        seq.truth[2 * t..2 * t + 2].copy_from_slice(&tracker.state().0);
    }
    let data = vec![seq];
    let g = batch_grad(
        &model,
        &data,
        &[Window { sequence: 0, start: 0, mean0: vec![0.0, 0.0], position_shift: vec![0.0] }],
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
        se += (v - test.truth_at(t)[1]).powi(2);
        base += test.truth_at(t)[1].powi(2);
    }
    assert!(se < 0.25 * base, "velocity error {se} vs zero-velocity baseline {base}");
}

/// The parts of a batch's gradient, and the tree their gradients are
/// summed along, do not depend on the thread count, so neither does the
/// model file, byte for byte: with parts of one window (7 of them per batch
/// of 7, an odd count that 2 and 3 threads split unevenly), of the default
/// size and of 3. Catches any reduction whose order follows the threads or
/// the scheduling (rayon's `reduce` or `sum` over the parts, sums in the
/// order the parts finish, shards of `batch / threads` windows).
#[test]
fn the_same_seed_gives_the_same_model_file_on_any_number_of_threads() {
    let data: Vec<Sequence> = (0..4).map(|s| synthetic(200, s)).collect();
    let trained = |threads: usize, part_windows: usize| {
        let mut model = DekfModel::new(meta(2), &mut ChaCha8Rng::seed_from_u64(3));
        let cfg = TrainConfig {
            schedule: vec![Stage { length: 4, epochs: 2 }, Stage { length: 8, epochs: 1 }],
            batch_size: 7,
            threads,
            part_windows,
            ..TrainConfig::default()
        };
        train(&mut model, &data, &cfg, &mut |_| {});
        file::to_bytes(&model).expect("a model file")
    };
    for part_windows in [1, DEFAULT_PART_WINDOWS, 3] {
        let one = trained(1, part_windows);
        for threads in [2, 3] {
            assert!(
                one == trained(threads, part_windows),
                "1 and {threads} threads, parts of {part_windows}"
            );
        }
    }
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
            assert!(out.mean.iter().all(|x| x.is_finite()) && out.cov.iter().all(|x| x.is_finite()));
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
