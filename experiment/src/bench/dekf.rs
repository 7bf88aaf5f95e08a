//! The dEKF's speed (`bench --what dekf,dekf-training`) against the
//! targets of the speed issue (29): one online step (derivative filter
//! included) at most 8 us on one core (the thesis ran at 119 Hz), and
//! training on a thesis-sized set (50 sessions of 60 s at 30 Hz, 25
//! epochs) at most 180 s on 2 cores (the thesis: 22 min 55 s per object).

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

/// Target time of one online step (s): issue 29's 8 us.
const STEP_TARGET_S: f64 = 8e-6;
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
    let (mut per_step, mut cpu_per_step) = (Vec::new(), Vec::new());
    let mut checksum = 0.0;
    for _ in 0..runs.max(1) {
        let mut tracker = DekfTracker::new(&model);
        let (started, cpu_started) = (Instant::now(), thread_cpu_s()?);
        for (k, z) in scans.iter().enumerate() {
            if let Some(o) = tracker.on_scan(k as f64 * 0.01, z) {
                checksum += o.mean[0];
            }
        }
        per_step.push(started.elapsed().as_secs_f64() / STEPS as f64);
        cpu_per_step.push((thread_cpu_s()? - cpu_started) / STEPS as f64);
    }
    let m = median(&per_step);
    Ok(json!({
        "what": "one dEKF step with the derivative filter (xy, 6 channels), one core",
        "median_us": m * 1e6,
        "runs_us": per_step.iter().map(|s| s * 1e6).collect::<Vec<_>>(),
        "cpu_median_us": median(&cpu_per_step) * 1e6,
        "target_us": STEP_TARGET_S * 1e6,
        "rate_hz": 1.0 / m,
        "thesis_rate_hz": 119.0,
        "pass": m <= STEP_TARGET_S,
        "checksum": checksum.is_finite(),
    }))
}

/// CPU time of the calling thread (s): what a step costs when other
/// processes share the core (wall time then counts their turns too).
fn thread_cpu_s() -> Result<f64> {
    use nix::time::{ClockId, clock_gettime};
    let t = clock_gettime(ClockId::CLOCK_THREAD_CPUTIME_ID)
        .map_err(|e| anyhow::anyhow!("cannot read the thread's CPU time: {e}"))?;
    Ok(t.tv_sec() as f64 + t.tv_nsec() as f64 * 1e-9)
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

/// The median time of `runs` trainings of `spec` and what they trained.
struct Timed {
    median_s: f64,
    runs_s: Vec<f64>,
    params: Vec<f32>,
    steps: u64,
    rmse: [f64; 2],
}

fn timed(
    spec: &TrainSpec,
    sessions: &[SessionData],
    runs: usize,
    fit: &mut dyn FnMut(&TrainSpec, &[SessionData]) -> Result<Trained>,
) -> Result<Timed> {
    let mut t =
        Timed { median_s: 0.0, runs_s: Vec::new(), params: Vec::new(), steps: 0, rmse: [f64::NAN; 2] };
    for _ in 0..runs.max(1) {
        let trained = fit(spec, sessions)?;
        t.runs_s.push(trained.seconds);
        t.steps = trained.model.meta.training["steps"].as_u64().unwrap_or(0);
        t.rmse = trained.epochs.last().map_or(t.rmse, |e| e.rmse);
        t.params = trained.model.params;
    }
    t.median_s = median(&t.runs_s);
    Ok(t)
}

/// Trains the default schedule on `sessions` simulated sessions of 60 s
/// (the thesis-sized set: 50) with `threads` workers, `runs` times, each
/// with `fit`; reports the median. With more than one thread it trains on
/// one thread too and reports the speed-up and whether both trained the
/// same model, byte for byte. Time per sample-step: the training's time
/// over the filter steps it ran, every step of the set once per epoch.
pub fn training(
    dir: &Path,
    runs: usize,
    threads: usize,
    sessions: u32,
    fit: &mut dyn FnMut(&TrainSpec, &[SessionData]) -> Result<Trained>,
) -> Result<Value> {
    let collected = Instant::now();
    let files = thesis_sized_set(dir, sessions, 60.0)?;
    let collect_s = collected.elapsed().as_secs_f64();
    let spec = TrainSpec {
        channels: ChannelSet::Xy.names(),
        seed: 1,
        threads,
        truth: TruthSource::Sim,
        ..TrainSpec::default()
    };
    let data = files.iter().map(|f| load(f, Some(spec.truth))).collect::<Result<Vec<_>>>()?;
    let many = timed(&spec, &data, runs, fit)?;
    let one = (threads != 1)
        .then(|| timed(&TrainSpec { threads: 1, ..spec.clone() }, &data, runs, fit))
        .transpose()?;
    let epochs: usize = spec.schedule.iter().map(|s| s.epochs).sum();
    let us_per_sample_step = |s: f64| s * 1e6 / (many.steps as f64 * epochs as f64);
    let m = many.median_s;
    Ok(json!({
        "what": format!("dEKF training: {sessions} simulated sessions of 60 s at 30 Hz, schedule 2,4,8,16,32 x 5 epochs, batch 32"),
        "threads": threads,
        "filter_steps": many.steps,
        "median_s": m,
        "runs_s": many.runs_s,
        "us_per_sample_step": us_per_sample_step(m),
        "one_thread": one.as_ref().map(|o| json!({
            "median_s": o.median_s,
            "runs_s": o.runs_s,
            "us_per_sample_step": us_per_sample_step(o.median_s),
            "speedup": o.median_s / m,
            "same_model": o.params == many.params,
        })),
        "target_s": TRAINING_TARGET_S * f64::from(sessions) / 50.0,
        "thesis_s": 22.0 * 60.0 + 55.0,
        "pass": m <= TRAINING_TARGET_S * f64::from(sessions) / 50.0,
        "final_training_rmse": {"position_cm": many.rmse[0], "velocity_cmps": many.rmse[1]},
        "collect_s": collect_s,
    }))
}

/// One line for humans from a result of [`step`] or [`training`].
pub fn describe(r: &Value) -> String {
    let pass = if r["pass"].as_bool() == Some(true) { "PASS" } else { "FAIL" };
    if let Some(us) = r["median_us"].as_f64() {
        format!(
            "{}: median {us:.2} us per step ({:.2} us of CPU time; {:.0} Hz; thesis 119 Hz), target <= {:.0} us: {pass}",
            r["what"].as_str().unwrap_or(""),
            r["cpu_median_us"].as_f64().unwrap_or(f64::NAN),
            r["rate_hz"].as_f64().unwrap_or(f64::NAN),
            r["target_us"].as_f64().unwrap_or(f64::NAN)
        )
    } else {
        let line = format!(
            "{}, {} threads: median {:.1} s, {:.2} us per sample-step (thesis 1375 s), target <= {:.0} s: {pass}",
            r["what"].as_str().unwrap_or(""),
            r["threads"],
            r["median_s"].as_f64().unwrap_or(f64::NAN),
            r["us_per_sample_step"].as_f64().unwrap_or(f64::NAN),
            r["target_s"].as_f64().unwrap_or(f64::NAN)
        );
        let one = &r["one_thread"];
        match one["median_s"].as_f64() {
            Some(s) => format!(
                "{line}\n  1 thread: median {s:.1} s, {:.2} us per sample-step; speed-up {:.2}x on {} threads; same model: {}",
                one["us_per_sample_step"].as_f64().unwrap_or(f64::NAN),
                one["speedup"].as_f64().unwrap_or(f64::NAN),
                r["threads"],
                one["same_model"]
            ),
            None => line,
        }
    }
}

#[cfg(test)]
mod tests {
    /// The step's report: issue 29's 8 us target (it printed the dEKF
    /// issue's 20 us after the target changed) and the step's CPU time,
    /// which cannot exceed its wall time.
    #[test]
    fn the_step_is_reported_against_8_us_with_its_cpu_time() {
        let r = super::step(1).expect("the step bench runs");
        assert_eq!(r["target_us"].as_f64(), Some(8.0));
        let (wall, cpu) = (r["median_us"].as_f64().unwrap(), r["cpu_median_us"].as_f64().unwrap());
        assert!(cpu > 0.0 && cpu <= wall * 1.01 + 0.1, "CPU {cpu} us, wall {wall} us");
        let line = super::describe(&r);
        assert!(line.contains("target <= 8 us") && line.contains("us of CPU time"), "{line}");
    }
}
