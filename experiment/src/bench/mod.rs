//! Speed measurements (`bench`): collection (the caller pins it to two
//! cores) against the targets of issue 29 (camera: 30x real time; no camera:
//! 200x), what the live view costs it (on one core), and the dEKF's step and
//! training times.

pub mod dekf;
pub mod live;
pub mod ros2;
pub mod training;

use std::path::Path;
use std::sync::atomic::AtomicBool;

use anyhow::Result;
use serde_json::json;
use slidetrack_sim::ObjectConfig;

use crate::rig::TrialSpec;
use crate::rig_config::RigConfig;
use crate::trial::run_sim_trial;

/// Speed targets (multiples of real time).
const CAMERA_TARGET: f64 = 30.0;
const NO_CAMERA_TARGET: f64 = 200.0;

/// How the trials of a measurement run.
#[derive(Clone, Copy, Debug)]
pub struct BenchOptions {
    /// Runs per measurement (the median is reported).
    pub runs: usize,
    /// Duration of the sliding cycles of each trial (s).
    pub duration_s: f64,
}

/// Median of `v` (NaN when empty).
fn median(v: &[f64]) -> f64 {
    let mut v = v.to_vec();
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n == 0 {
        f64::NAN
    } else if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// OpenCV on one thread, so that a measurement pinned to one core uses one.
pub fn use_one_thread() {
    slidetrack_calibration::use_one_thread();
}

/// The collection speed of one kind of trial.
#[derive(Clone, Debug)]
pub struct CollectMeasurement {
    /// What was measured.
    pub label: &'static str,
    /// The target (multiple of real time).
    pub target: f64,
    /// Wall time of each run (s).
    pub wall_s: Vec<f64>,
    /// Session time of a run (s).
    pub session_s: f64,
}

impl CollectMeasurement {
    /// Median wall time of the runs (s).
    pub fn median_s(&self) -> f64 {
        median(&self.wall_s)
    }

    /// Multiple of real time of the median run.
    pub fn speedup(&self) -> f64 {
        self.session_s / self.median_s()
    }

    /// The measurement as JSON.
    pub fn to_json(&self) -> serde_json::Value {
        json!({
            "what": self.label,
            "session_s": self.session_s,
            "median_wall_s": self.median_s(),
            "runs_wall_s": self.wall_s,
            "times_real_time": self.speedup(),
            "target_times_real_time": self.target,
            "pass": self.speedup() >= self.target,
        })
    }
}

/// Collection speed with and without camera, sessions written in `dir`.
pub fn collect(args: &BenchOptions, dir: &Path) -> Result<Vec<CollectMeasurement>> {
    use_one_thread();
    let rig = RigConfig::default();
    let object = ObjectConfig::load("box")?;
    let stop = AtomicBool::new(false);
    let mut results = Vec::new();
    for (label, camera, target) in
        [("with camera + marker detection", true, CAMERA_TARGET), ("without camera", false, NO_CAMERA_TARGET)]
    {
        let mut m = CollectMeasurement { label, target, wall_s: Vec::new(), session_s: 0.0 };
        for run in 0..args.runs.max(1) {
            let spec = TrialSpec {
                rig: &rig,
                object: &object,
                seed: 1,
                trial: run as u32,
                duration_s: args.duration_s,
                camera,
                realtime: false,
                overwrite: true,
                path: dir.join(format!("bench-{camera}-{run}.mcap")),
                live: None,
            };
            let report = run_sim_trial(&spec, &stop, &mut |_| {})?;
            m.wall_s.push(report.wall_s);
            m.session_s = report.outcome.end.as_secs_f64();
            let _ = std::fs::remove_file(&spec.path);
        }
        results.push(m);
    }
    Ok(results)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_median_of_an_even_count_is_the_mean_of_the_middle_two() {
        assert_eq!(median(&[3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(&[4.0, 1.0, 2.0, 3.0]), 2.5);
    }
}
