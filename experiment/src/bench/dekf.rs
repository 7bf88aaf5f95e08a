//! The dEKF's speed (`bench --what dekf,dekf-training`) against the
//! targets of the dEKF issue: one online step (derivative filter included) at
//! most 20 us on one core (the thesis ran at 119 Hz), and training on a
//! thesis-sized set (50 sessions of 60 s at 30 Hz, 25 epochs) at most 180 s
//! on 2 cores (the thesis: 22 min 55 s per object).

use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;
use std::time::Instant;

use anyhow::Result;
use rand::SeedableRng;
use serde_json::{Value, json};
use slidetrack_estimators::dekf::{DekfModel, DekfTracker, Measurement, ModelMeta, StateKind};
use slidetrack_estimators::derivative::DerivativeFilterConfig;
use slidetrack_sim::ObjectConfig;

use super::median;
use crate::dataset::{ChannelSet, SessionData, TruthSource, load};
use crate::dekf_train::{TrainSpec, Trained};
use crate::rig::TrialSpec;
use crate::rig_config::RigConfig;
use crate::trial::{run_sim_trial, session_file_name};

/// Target time of one online step (s).
const STEP_TARGET_S: f64 = 20e-6;
/// Target time of a thesis-sized training (s).
const TRAINING_TARGET_S: f64 = 180.0;

/// Time per online step of an `xy` model filtering every scan, median of `runs`.
pub fn step(runs: usize) -> Result<Value> {
    let channels = ChannelSet::Xy.names();
    let meta = ModelMeta {
        dt_s: 0.01,
        decimation: 1,
        tactile_rate_hz: 100.0,
        channels: channels.clone(),
        measurement: Measurement::Derivative,
        derivative_filter: DerivativeFilterConfig::default(),
        state: StateKind::Sliding,
        state_units: StateKind::Sliding.units(),
        p0_diag: StateKind::Sliding.default_p0_diag(),
        training: json!({}),
        software_version: env!("CARGO_PKG_VERSION").into(),
    };
    let model = DekfModel::new(meta, &mut rand_chacha::ChaCha8Rng::seed_from_u64(1));
    const STEPS: usize = 20_000;
    // A stick-slip-like signal: slow ramps with a 1 s period, plus a wobble.
    let scans: Vec<Vec<f64>> = (0..STEPS)
        .map(|k| {
            let t = k as f64 * 0.01;
            (0..channels.len()).map(|c| 40.0 * (t + c as f64).sin() + 3.0 * (37.0 * t).sin()).collect()
        })
        .collect();
    let mut per_step = Vec::new();
    let mut checksum = 0.0;
    for _ in 0..runs.max(1) {
        let mut tracker = DekfTracker::new(&model);
        let started = Instant::now();
        for (k, z) in scans.iter().enumerate() {
            if let Some(o) = tracker.on_scan(k as f64 * 0.01, z) {
                checksum += o.mean[0];
            }
        }
        per_step.push(started.elapsed().as_secs_f64() / STEPS as f64);
    }
    let m = median(&per_step);
    Ok(json!({
        "what": "one dEKF step with the derivative filter (xy, 6 channels), one core",
        "median_us": m * 1e6,
        "runs_us": per_step.iter().map(|s| s * 1e6).collect::<Vec<_>>(),
        "target_us": STEP_TARGET_S * 1e6,
        "rate_hz": 1.0 / m,
        "thesis_rate_hz": 119.0,
        "pass": m <= STEP_TARGET_S,
        "checksum": checksum.is_finite(),
    }))
}

/// Collects `n` simulated 60 s sessions without camera (with the simulator's truth) into `dir`.
fn thesis_sized_set(dir: &Path, n: u32, duration_s: f64) -> Result<Vec<PathBuf>> {
    let rig = RigConfig::default();
    let object = ObjectConfig::load("box")?;
    let stop = AtomicBool::new(false);
    (0..n)
        .map(|trial| {
            let spec = TrialSpec {
                rig: &rig,
                object: &object,
                seed: 7,
                trial,
                duration_s,
                camera: false,
                realtime: false,
                overwrite: true,
                path: dir.join(session_file_name("box", 7, trial)),
                live: None,
            };
            Ok(run_sim_trial(&spec, &stop, &mut |_| {})?.path)
        })
        .collect()
}

/// Trains the default schedule on 50 simulated sessions of 60 s with
/// `threads` workers, `runs` times, each with `fit`; reports the median.
pub fn training(
    dir: &Path,
    runs: usize,
    threads: usize,
    fit: &mut dyn FnMut(&TrainSpec, &[SessionData]) -> Result<Trained>,
) -> Result<Value> {
    let collected = Instant::now();
    let files = thesis_sized_set(dir, 50, 60.0)?;
    let collect_s = collected.elapsed().as_secs_f64();
    let spec = TrainSpec {
        channels: ChannelSet::Xy.names(),
        seed: 1,
        threads,
        truth: TruthSource::Sim,
        ..TrainSpec::default()
    };
    let sessions = files.iter().map(|f| load(f, Some(spec.truth))).collect::<Result<Vec<_>>>()?;
    let mut seconds = Vec::new();
    let mut steps = 0;
    let mut rmse = [f64::NAN; 2];
    for _ in 0..runs.max(1) {
        let trained = fit(&spec, &sessions)?;
        seconds.push(trained.seconds);
        steps = trained.model.meta.training["steps"].as_u64().unwrap_or(0);
        rmse = trained.epochs.last().map_or(rmse, |e| e.rmse);
    }
    let m = median(&seconds);
    Ok(json!({
        "what": "dEKF training: 50 simulated sessions of 60 s at 30 Hz, schedule 2,4,8,16,32 x 5 epochs, batch 32",
        "threads": threads,
        "filter_steps": steps,
        "median_s": m,
        "runs_s": seconds,
        "target_s": TRAINING_TARGET_S,
        "thesis_s": 22.0 * 60.0 + 55.0,
        "pass": m <= TRAINING_TARGET_S,
        "final_training_rmse": {"position_cm": rmse[0], "velocity_cmps": rmse[1]},
        "collect_s": collect_s,
    }))
}

/// One line for humans from a result of [`step`] or [`training`].
pub fn describe(r: &Value) -> String {
    let pass = if r["pass"].as_bool() == Some(true) { "PASS" } else { "FAIL" };
    if let Some(us) = r["median_us"].as_f64() {
        format!(
            "{}: median {us:.2} us per step ({:.0} Hz; thesis 119 Hz), target <= {:.0} us: {pass}",
            r["what"].as_str().unwrap_or(""),
            r["rate_hz"].as_f64().unwrap_or(f64::NAN),
            r["target_us"].as_f64().unwrap_or(f64::NAN)
        )
    } else {
        format!(
            "{}, {} threads: median {:.1} s (thesis 1375 s), target <= {:.0} s: {pass}",
            r["what"].as_str().unwrap_or(""),
            r["threads"],
            r["median_s"].as_f64().unwrap_or(f64::NAN),
            r["target_s"].as_f64().unwrap_or(f64::NAN)
        )
    }
}
