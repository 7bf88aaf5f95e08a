//! The dEKF's online speed (`bench --what dekf`) against the target of the
//! speed issue (29): one online step (derivative filter included) at most
//! 8 us on one core (the thesis ran at 119 Hz). The training's speed is
//! [`super::training`].

use std::time::Instant;

use anyhow::Result;
use rand::SeedableRng;
use serde_json::{Value, json};
use slidetrack_estimators::dekf::{DekfModel, DekfTracker, Measurement, ModelMeta, StateKind};
use slidetrack_estimators::derivative::DerivativeFilterConfig;

use super::median;
use crate::dataset::ChannelSet;

/// Target time of one online step (s): issue 29's 8 us.
const STEP_TARGET_S: f64 = 8e-6;

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

/// One line for humans from a result of [`step`].
pub fn describe(r: &Value) -> String {
    let pass = if r["pass"].as_bool() == Some(true) { "PASS" } else { "FAIL" };
    format!(
        "{}: median {:.2} us per step ({:.2} us of CPU time; {:.0} Hz; thesis 119 Hz), target <= {:.0} us: {pass}",
        r["what"].as_str().unwrap_or(""),
        r["median_us"].as_f64().unwrap_or(f64::NAN),
        r["cpu_median_us"].as_f64().unwrap_or(f64::NAN),
        r["rate_hz"].as_f64().unwrap_or(f64::NAN),
        r["target_us"].as_f64().unwrap_or(f64::NAN)
    )
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
