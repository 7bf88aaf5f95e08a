//! The dEKF's golden file (`tests/golden/`): three small models as
//! slidetrack writes them, inputs, and the outputs slidetrack computes for
//! them. Both of slidetrack's executors of the network's list of layers (the
//! batched pass of training, [`super::mlp`], and the fast online pass,
//! `infer`) are checked against it here; both Python twins
//! (`tests/python/dekf_reference.py`, `scripts/dekf_torch_train.py`) in
//! `tests/dekf_golden.rs`. `docs/model-format.md` describes the file.
//!
//! Regenerate it (after a deliberate change of the format or of the
//! arithmetic) with
//! `cargo test -p slidetrack-estimators write_the_golden_file -- --ignored`.
//!
//! What each part catches: the network probes (values and Jacobians of
//! every network at a few inputs) a layer left out, swapped or read from
//! the wrong tensor, a wrong activation or slope, a weight read
//! transposed, a residual connection missing; the filter (twelve steps from
//! `mu0 = 0`, one of them with a missing value) a wrong normalisation of
//! the measurement, `F`, `Q = L_Q L_Q^T` (the whole lower triangle is set),
//! `R`, the gain or the Joseph update, a missing value not skipped.

use std::path::{Path, PathBuf};

use nalgebra::DMatrix;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde_json::{Value, json};

use super::file::{from_bytes, to_bytes};
use super::infer::FastNet;
use super::mlp::forward;
use super::params::{Activation, Architecture, Layer, NetAt};
use super::*;
use crate::derivative::DerivativeFilterConfig;

/// The golden file's JSON (inputs and outputs; the models are beside it).
pub const JSON: &str = "dekf.json";

/// Filter steps of every model.
const STEPS: usize = 12;

/// The step whose measurement misses a value (prediction only).
const MISSING_STEP: usize = 5;

/// Tolerances of slidetrack's executors against the file, relative to
/// `max(|expected|, 1)`. The networks run in `f32`: a different order of
/// the sums (another CPU's kernels, the fast path's columns against the
/// batched pass's matrix products) moves an output by a few `f32` ulps
/// (measured: below 1e-6); the bugs the file catches move them by 1e-2 or
/// more (`a_mutated_network_misses_the_golden_file`).
pub const NETWORK_TOLERANCE: f64 = 1e-5;

/// Tolerance of the filter's mean and covariance (the covariance relative
/// to its largest element): the network roundings, amplified over twelve
/// steps (measured: below 1e-6).
pub const FILTER_TOLERANCE: f64 = 1e-5;

/// One golden model.
struct Case {
    name: &'static str,
    state: StateKind,
    channels: usize,
    arch: Architecture,
    seed: u64,
}

/// A sliding model with ReLU and two shared blocks, one with tanh and none
/// (the encoder's block alone), a planar one with GELU (three outputs).
fn cases() -> [Case; 3] {
    let arch = |width, residual_blocks, activation| Architecture { width, residual_blocks, activation };
    [
        Case {
            name: "sliding-relu",
            state: StateKind::Sliding,
            channels: 4,
            arch: arch(8, 2, Activation::Relu),
            seed: 1,
        },
        Case {
            name: "sliding-tanh",
            state: StateKind::Sliding,
            channels: 3,
            arch: arch(5, 0, Activation::Tanh),
            seed: 2,
        },
        Case {
            name: "planar-gelu",
            state: StateKind::Planar,
            channels: 4,
            arch: arch(6, 1, Activation::Gelu),
            seed: 3,
        },
    ]
}

fn dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/golden")
}

fn file_name(name: &str) -> String {
    format!("dekf-{name}.safetensors")
}

/// The model of `case`: PyTorch's initialisation with doubled biases (units
/// away from their linear region and ReLU's kink), a full lower triangle in
/// `L_Q` and `L_R`, and a normalisation that is neither 0 nor 1.
fn model(case: &Case) -> DekfModel {
    let meta = ModelMeta {
        dt_s: 0.05,
        decimation: 1,
        tactile_rate_hz: 20.0,
        channels: (0..case.channels).map(|c| format!("ch{c}")).collect(),
        measurement: Measurement::Derivative,
        derivative_filter: DerivativeFilterConfig::default(),
        state: case.state,
        state_units: case.state.units(),
        p0_diag: case.state.default_p0_diag(),
        training: json!({ "by": "estimators/src/dekf/golden.rs", "seed": case.seed }),
        software_version: "golden".into(),
    };
    let mut rng = ChaCha8Rng::seed_from_u64(case.seed);
    let mut m = DekfModel::with_architecture(meta, &case.arch, &mut rng);
    let l = m.layout.clone();
    for net in [&l.motion, &l.measurement, &l.feature] {
        for at in net.linears() {
            m.params[at.bias..at.bias + at.out].iter_mut().for_each(|b| *b *= 2.0);
        }
    }
    for (offset, k) in [(l.process_noise, l.state.dim()), (l.measurement_noise, l.state.dofs())] {
        for r in 0..k {
            for c in 0..r {
                m.params[offset + r * k + c] = rng.random_range(-0.1..0.1);
            }
            m.params[offset + r * k + r] = rng.random_range(0.2..0.6);
        }
    }
    let mean: Vec<f32> = (0..l.channels).map(|_| rng.random_range(-2.0..2.0)).collect();
    let std: Vec<f32> = (0..l.channels).map(|_| rng.random_range(0.5..2.0)).collect();
    m.set_input_normalisation(&mean, &std);
    m
}

/// `xs` with tangent columns: `[x, e_0, .., e_(n-1)]` per sample.
fn with_tangents(x: &[f32]) -> DMatrix<f32> {
    let n = x.len();
    DMatrix::from_fn(n, n + 1, |r, c| {
        if c == 0 {
            x[r]
        } else if c == r + 1 {
            1.0
        } else {
            0.0
        }
    })
}

/// The batched pass on one input: the output and, with `jacobian`, its
/// Jacobian (`outputs x inputs`, row by row).
fn batched(p: &[f32], net: &NetAt, x: &[f32], jacobian: bool) -> (Vec<f64>, Vec<Vec<f64>>) {
    let (xs, cols) = if jacobian {
        (with_tangents(x), x.len() + 1)
    } else {
        (DMatrix::from_column_slice(x.len(), 1, x), 1)
    };
    let (y, _) = forward(p, net, xs, cols, false);
    let value = y.column(0).iter().map(|v| f64::from(*v)).collect();
    let jac = if jacobian {
        y.row_iter().map(|r| r.iter().skip(1).map(|v| f64::from(*v)).collect()).collect()
    } else {
        Vec::new()
    };
    (value, jac)
}

/// Random inputs of one network: `count` vectors of `n` values in `±scale`.
fn inputs(rng: &mut ChaCha8Rng, count: usize, n: usize, scale: f32) -> Vec<Vec<f32>> {
    (0..count).map(|_| (0..n).map(|_| rng.random_range(-scale..scale)).collect()).collect()
}

/// The measurements of the filter: `STEPS` vectors, unnormalised, one value
/// missing (NaN; `null` in the file) at [`MISSING_STEP`].
fn measurements(rng: &mut ChaCha8Rng, channels: usize) -> Vec<Vec<f64>> {
    let mut m: Vec<Vec<f64>> =
        (0..STEPS).map(|_| (0..channels).map(|_| rng.random_range(-3.0..3.0)).collect()).collect();
    m[MISSING_STEP][channels - 1] = f64::NAN;
    m
}

/// The golden entry of `case`: its network probes (the batched pass) and
/// its filter (the online filter, [`DekfTracker`]).
fn golden(case: &Case, m: &DekfModel) -> Value {
    let mut rng = ChaCha8Rng::seed_from_u64(100 + case.seed);
    let (l, n) = (&m.layout, m.state().dim());
    let mut probes = serde_json::Map::new();
    for (name, net, jacobian, size, scale) in [
        ("motion", &l.motion, true, n, 3.0),
        ("measurement", &l.measurement, true, n, 3.0),
        ("feature", &l.feature, false, l.channels, 2.0),
    ] {
        let rows: Vec<Value> = inputs(&mut rng, 4, size, scale)
            .iter()
            .map(|x| {
                let (output, jac) = batched(&m.params, net, x, jacobian);
                let mut row = json!({ "input": x, "output": output });
                if jacobian {
                    row["jacobian"] = json!(jac);
                }
                row
            })
            .collect();
        probes.insert(name.into(), Value::Array(rows));
    }
    let meas = measurements(&mut rng, l.channels);
    let mut tracker = DekfTracker::new(m);
    let (mut mean, mut cov, mut corrected) = (Vec::new(), Vec::new(), Vec::new());
    for z in &meas {
        corrected.push(tracker.step(z));
        let (mu, p) = tracker.state();
        mean.push(mu);
        cov.push(p);
    }
    let meas: Vec<Vec<Option<f64>>> =
        meas.iter().map(|z| z.iter().map(|v| v.is_finite().then_some(*v)).collect()).collect();
    json!({
        "name": case.name,
        "file": file_name(case.name),
        "state": m.state().name(),
        "architecture": m.architecture(),
        "networks": probes,
        "filter": { "measurements": meas, "mean": mean, "cov": cov, "corrected": corrected },
    })
}

/// `v` as JSON with every array of numbers on one line (a diff of the file
/// then shows which values moved).
fn compact(v: &Value, indent: usize, out: &mut String) {
    let pad = "  ".repeat(indent + 1);
    match v {
        Value::Array(items) if items.iter().any(|i| i.is_array() || i.is_object()) => {
            out.push_str("[\n");
            for (k, item) in items.iter().enumerate() {
                out.push_str(&pad);
                compact(item, indent + 1, out);
                out.push_str(if k + 1 < items.len() { ",\n" } else { "\n" });
            }
            out.push_str(&"  ".repeat(indent));
            out.push(']');
        }
        Value::Object(map) => {
            out.push_str("{\n");
            for (k, (key, item)) in map.iter().enumerate() {
                out.push_str(&format!("{pad}{}: ", Value::String(key.clone())));
                compact(item, indent + 1, out);
                out.push_str(if k + 1 < map.len() { ",\n" } else { "\n" });
            }
            out.push_str(&"  ".repeat(indent));
            out.push('}');
        }
        other => out.push_str(&other.to_string()),
    }
}

/// Every number of `v` (arrays flattened, `null` as NaN).
fn numbers(v: &Value) -> Vec<f64> {
    match v {
        Value::Array(items) => items.iter().flat_map(numbers).collect(),
        Value::Null => vec![f64::NAN],
        other => vec![other.as_f64().expect("a number")],
    }
}

/// The largest `|got - want| / max(|want|, floor)`.
fn worst(got: &[f64], want: &[f64], floor: f64) -> f64 {
    assert_eq!(got.len(), want.len(), "as many values as the golden file");
    got.iter().zip(want).map(|(g, w)| (g - w).abs() / w.abs().max(floor)).fold(0.0, f64::max)
}

/// How far slidetrack's executors are from one golden entry.
#[derive(Debug)]
struct Differences {
    /// The batched pass's network outputs and Jacobians.
    batched: f64,
    /// The fast online pass's (sliding models: networks of one output).
    fast: f64,
    /// The online filter's means.
    mean: f64,
    /// The online filter's covariances, relative to their largest element.
    cov: f64,
    /// The training filter's means (root mean square over the steps).
    training: f64,
    /// Whether the online filter corrected at the steps the file says.
    corrected_as_golden: bool,
}

/// The golden models and entries, read from the files.
fn read() -> Vec<(DekfModel, Value)> {
    let text = std::fs::read_to_string(dir().join(JSON)).expect("tests/golden/dekf.json");
    let golden: Value = serde_json::from_str(&text).expect("the golden JSON");
    let entries = golden["models"].as_array().expect("models").clone();
    entries
        .into_iter()
        .map(|entry| {
            let path = dir().join(entry["file"].as_str().expect("a file name"));
            let model = from_bytes(&std::fs::read(&path).expect("a golden model")).expect("a model file");
            (model, entry)
        })
        .collect()
}

/// Runs both executors (and the filters built on them) on `entry`.
fn check(m: &DekfModel, entry: &Value) -> Differences {
    let mut d = Differences {
        batched: 0.0,
        fast: 0.0,
        mean: 0.0,
        cov: 0.0,
        training: 0.0,
        corrected_as_golden: true,
    };
    let l = &m.layout;
    for (name, net) in [("motion", &l.motion), ("measurement", &l.measurement), ("feature", &l.feature)] {
        let mut fast = (net.outputs() == 1).then(|| FastNet::new(&m.params, net));
        for probe in entry["networks"][name].as_array().expect("probes") {
            let x: Vec<f32> = numbers(&probe["input"]).iter().map(|v| *v as f32).collect();
            let jacobian = !probe["jacobian"].is_null();
            let mut want = numbers(&probe["output"]);
            want.extend(numbers(&probe["jacobian"]).iter().filter(|_| jacobian));
            let (value, jac) = batched(&m.params, net, &x, jacobian);
            let got: Vec<f64> = value.into_iter().chain(jac.into_iter().flatten()).collect();
            d.batched = d.batched.max(worst(&got, &want, 1.0));
            let Some(fast) = fast.as_mut() else { continue };
            let got: Vec<f64> = if jacobian {
                let (v, g) = fast.value_and_gradient([x[0], x[1]]);
                [v, g[0], g[1]].iter().map(|v| f64::from(*v)).collect()
            } else {
                vec![f64::from(fast.value(&x))]
            };
            d.fast = d.fast.max(worst(&got, &want, 1.0));
        }
    }
    let filter = &entry["filter"];
    let meas: Vec<Vec<f64>> = filter["measurements"].as_array().expect("steps").iter().map(numbers).collect();
    let mut tracker = DekfTracker::new(m);
    for (k, z) in meas.iter().enumerate() {
        d.corrected_as_golden &= Value::Bool(tracker.step(z)) == filter["corrected"][k];
        let (mean, cov) = tracker.state();
        d.mean = d.mean.max(worst(&mean, &numbers(&filter["mean"][k]), 1.0));
        let want = numbers(&filter["cov"][k]);
        let largest = want.iter().fold(0.0, |a: f64, b| a.max(b.abs()));
        d.cov = d.cov.max(worst(&cov, &want, largest));
    }
    d.training = training_filter(m, &meas, &numbers(&filter["mean"]));
    d
}

/// The training filter (the batched pass inside [`batch_grad`]) over the
/// golden measurements from `mu0 = 0`, scored against the golden means:
/// the root mean square of its error, relative to the largest mean.
fn training_filter(m: &DekfModel, meas: &[Vec<f64>], means: &[f64]) -> f64 {
    let (n, c) = (m.state().dim(), m.layout.channels);
    let mut measurements = vec![0.0f32; c];
    let mut valid = vec![false];
    for z in meas {
        let mut x: Vec<f32> = z.iter().map(|v| if v.is_finite() { *v as f32 } else { 0.0 }).collect();
        m.normalise(&mut x);
        measurements.extend(x);
        valid.push(z.iter().all(|v| v.is_finite()));
    }
    let truth = std::iter::repeat_n(0.0, n).chain(means.iter().copied()).collect();
    let seq = Sequence { measurements, valid, truth, dim: n };
    let w =
        Window { sequence: 0, start: 0, mean0: vec![0.0; n], position_shift: vec![0.0; m.state().dofs()] };
    let g = batch_grad(m, &[seq], &[w], meas.len());
    let largest = means.iter().fold(1.0, |a: f64, b| a.max(b.abs()));
    (g.squared_error / g.states as f64).sqrt() / largest
}

/// Writes the golden file (the models and `dekf.json`); run it on purpose.
#[test]
#[ignore = "writes tests/golden/; run it to regenerate the golden file"]
fn write_the_golden_file() {
    std::fs::create_dir_all(dir()).expect("tests/golden");
    let mut models = Vec::new();
    for case in cases() {
        let m = model(&case);
        std::fs::write(dir().join(file_name(case.name)), to_bytes(&m).expect("model bytes"))
            .expect("a model file");
        // The entry of the model as read back, as every implementation reads it.
        let m = from_bytes(&to_bytes(&m).expect("model bytes")).expect("a model file");
        models.push(golden(&case, &m));
    }
    let golden = json!({
        "about": "the dEKF's golden file: see estimators/src/dekf/golden.rs and docs/model-format.md",
        "models": models,
    });
    let mut text = String::new();
    compact(&golden, 0, &mut text);
    text.push('\n');
    std::fs::write(dir().join(JSON), text).expect("tests/golden/dekf.json");
}

#[test]
fn both_executors_reproduce_the_golden_file() {
    let golden = read();
    assert_eq!(golden.len(), cases().len());
    for (m, entry) in &golden {
        let d = check(m, entry);
        eprintln!("{}: {d:?}", entry["name"]);
        assert!(d.batched < NETWORK_TOLERANCE, "{}: batched pass {d:?}", entry["name"]);
        assert!(d.fast < NETWORK_TOLERANCE, "{}: fast pass {d:?}", entry["name"]);
        assert!(d.corrected_as_golden, "{}: {d:?}", entry["name"]);
        for (what, v) in [("mean", d.mean), ("covariance", d.cov), ("training filter", d.training)] {
            assert!(v < FILTER_TOLERANCE, "{}: {what} {d:?}", entry["name"]);
        }
    }
    // The fast path ran on both sliding models.
    assert_eq!(golden.iter().filter(|(m, _)| m.state() == StateKind::Sliding).count(), 2);
}

/// A change of a network's list of layers: a bug the golden file must catch.
type Mutation = fn(&mut NetAt);

/// The encoder's activation and residual block swapped.
fn swap_layers(net: &mut NetAt) {
    net.layers.swap(1, 2);
}

/// Every activation another one (tanh, or GELU for tanh).
fn other_activation(net: &mut NetAt) {
    for layer in &mut net.layers {
        match layer {
            Layer::Activation(a) | Layer::Residual { activation: a, .. } => {
                *a = if *a == Activation::Tanh { Activation::Gelu } else { Activation::Tanh };
            }
            Layer::Linear(_) => {}
        }
    }
}

/// The encoder's activation left out.
fn no_activation(net: &mut NetAt) {
    net.layers.retain(|l| !matches!(l, Layer::Activation(_)));
}

/// The golden file catches the bugs it is there for: a network with two
/// layers swapped, with another activation, or without the encoder's
/// activation misses it by far more than the tolerance, in its network
/// probes and in its filter.
#[test]
fn a_mutated_network_misses_the_golden_file() {
    let mutations: [(&str, Mutation); 3] = [
        ("swapped layers", swap_layers),
        ("another activation", other_activation),
        ("no activation", no_activation),
    ];
    for (m, entry) in read() {
        for (what, mutate) in mutations {
            let mut mutant = m.clone();
            for net in [&mut mutant.layout.motion, &mut mutant.layout.measurement, &mut mutant.layout.feature]
            {
                mutate(net);
            }
            let d = check(&mutant, &entry);
            assert!(d.batched > 100.0 * NETWORK_TOLERANCE, "{} {what}: {d:?}", entry["name"]);
            assert!(d.mean > 100.0 * FILTER_TOLERANCE, "{} {what}: {d:?}", entry["name"]);
        }
    }
}
