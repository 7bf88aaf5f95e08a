//! `slidetrack bench`: collection speed on one core against the targets of
//! the foundation issue (camera: 10x real time; no camera: 200x), and the
//! dEKF's step and training times (see `bench_dekf`).

use std::sync::atomic::AtomicBool;

use anyhow::{Context, Result};
use serde_json::json;
use slidetrack_experiment::rig::TrialSpec;
use slidetrack_experiment::rig_config::RigConfig;
use slidetrack_experiment::trial::run_sim_trial;
use slidetrack_sim::ObjectConfig;

use crate::cli::{BenchArgs, BenchWhat};

/// Speed targets (multiples of real time).
const CAMERA_TARGET: f64 = 10.0;
const NO_CAMERA_TARGET: f64 = 200.0;

struct Measurement {
    label: &'static str,
    target: f64,
    wall_s: Vec<f64>,
    session_s: f64,
}

impl Measurement {
    fn median_s(&self) -> f64 {
        let mut v = self.wall_s.clone();
        v.sort_by(f64::total_cmp);
        let n = v.len();
        if n % 2 == 1 { v[n / 2] } else { 0.5 * (v[n / 2 - 1] + v[n / 2]) }
    }

    fn speedup(&self) -> f64 {
        self.session_s / self.median_s()
    }

    fn to_json(&self) -> serde_json::Value {
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

/// Pins this process (and the threads it starts, the recorder among them) to one CPU.
fn pin_to_one_core() -> Result<usize> {
    use nix::sched::{CpuSet, sched_getaffinity, sched_setaffinity};
    use nix::unistd::Pid;
    let allowed = sched_getaffinity(Pid::from_raw(0)).context("cannot read the CPU affinity")?;
    let cpu = (0..CpuSet::count()).find(|&c| allowed.is_set(c).unwrap_or(false)).unwrap_or(0);
    let mut one = CpuSet::new();
    one.set(cpu).context("cannot build the CPU set")?;
    sched_setaffinity(Pid::from_raw(0), &one).context("cannot pin to one CPU")?;
    Ok(cpu)
}

pub fn run(args: &BenchArgs) -> Result<()> {
    let dir = tempfile_dir()?;
    let result = run_in(args, &dir);
    let _ = std::fs::remove_dir_all(&dir);
    result
}

fn run_in(args: &BenchArgs, dir: &std::path::Path) -> Result<()> {
    let mut report = serde_json::Map::new();
    // Training first: it uses several cores, the others are pinned to one.
    if args.what.contains(&BenchWhat::DekfTraining) {
        let r = super::bench_dekf::training(dir, args.runs.clamp(1, 3), args.threads, args.json)?;
        if !args.json {
            println!("{}", super::bench_dekf::describe(&r));
        }
        report.insert("dekf_training".into(), r);
    }
    let cpu = pin_to_one_core()?;
    report.insert("cpu".into(), json!(cpu));
    if args.what.contains(&BenchWhat::Dekf) {
        let r = super::bench_dekf::step(args.runs)?;
        if !args.json {
            println!("{} (CPU {cpu})", super::bench_dekf::describe(&r));
        }
        report.insert("dekf_step".into(), r);
    }
    if args.what.contains(&BenchWhat::Collect) {
        let results = bench_collect(args, dir)?;
        if args.json {
            report.insert(
                "collect".into(),
                json!(results.iter().map(Measurement::to_json).collect::<Vec<_>>()),
            );
        } else {
            print_collect(args, cpu, &results);
        }
    }
    if args.what.contains(&BenchWhat::CollectLive) {
        if !args.json {
            println!("{}", super::bench_live::header(args, cpu));
        }
        report.insert("collect_live".into(), json!(super::bench_live::measure(args, dir)?));
    }
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    }
    Ok(())
}

/// Collection speed with and without camera.
fn bench_collect(args: &BenchArgs, dir: &std::path::Path) -> Result<Vec<Measurement>> {
    slidetrack_calibration::use_one_thread();
    let rig = RigConfig::default();
    let object = ObjectConfig::load("box")?;
    let stop = AtomicBool::new(false);
    let mut results = Vec::new();
    for (label, camera, target) in
        [("with camera + marker detection", true, CAMERA_TARGET), ("without camera", false, NO_CAMERA_TARGET)]
    {
        let mut m = Measurement { label, target, wall_s: Vec::new(), session_s: 0.0 };
        for run in 0..args.runs.max(1) {
            let spec = TrialSpec {
                rig: &rig,
                object: &object,
                seed: 1,
                trial: run as u32,
                duration_s: args.duration,
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

fn print_collect(args: &BenchArgs, cpu: usize, results: &[Measurement]) {
    println!(
        "collect: box, {} s of sliding cycles, pinned to CPU {cpu} (one core, OpenCV single-threaded), median of {} runs",
        args.duration,
        args.runs.max(1)
    );
    for m in results {
        println!(
            "  {:<32} {:>7.3} s for {:.1} s of session -> {:>6.1}x real time (target >= {:.0}x): {}",
            m.label,
            m.median_s(),
            m.session_s,
            m.speedup(),
            m.target,
            if m.speedup() >= m.target { "PASS" } else { "FAIL" }
        );
    }
}

fn tempfile_dir() -> Result<std::path::PathBuf> {
    let dir = std::env::temp_dir().join(format!("slidetrack-bench-{}", std::process::id()));
    std::fs::create_dir_all(&dir).with_context(|| format!("cannot create {}", dir.display()))?;
    Ok(dir)
}
