//! `slidetrack bench`: collection speed on two cores against the targets of
//! issue 29 (camera: 30x real time; no camera: 200x), and the dEKF's step and
//! training times (`slidetrack_experiment::bench`).

use anyhow::{Context, Result};
use serde_json::json;
use slidetrack_experiment::bench::training::{self, TrainingBench};
use slidetrack_experiment::bench::{self, BenchOptions, CollectMeasurement, dekf};
use slidetrack_experiment::dataset::SessionData;
use slidetrack_experiment::dekf_train::TrainSpec;

use crate::cli::{BenchArgs, BenchWhat};

/// The CPUs this process may run on, in order.
fn allowed_cpus() -> Result<Vec<usize>> {
    use nix::sched::{CpuSet, sched_getaffinity};
    use nix::unistd::Pid;
    let allowed = sched_getaffinity(Pid::from_raw(0)).context("cannot read the CPU affinity")?;
    Ok((0..CpuSet::count()).filter(|&c| allowed.is_set(c).unwrap_or(false)).collect())
}

/// Pins this process (and the threads it starts, the recorder among them) to `cpus`.
fn pin_to(cpus: &[usize]) -> Result<()> {
    use nix::sched::{CpuSet, sched_setaffinity};
    use nix::unistd::Pid;
    let mut set = CpuSet::new();
    for &cpu in cpus {
        set.set(cpu).context("cannot build the CPU set")?;
    }
    sched_setaffinity(Pid::from_raw(0), &set).with_context(|| format!("cannot pin to CPUs {cpus:?}"))
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
        let quiet = args.json;
        let mut fit = |spec: &TrainSpec, sessions: &[SessionData]| {
            super::train::fit_with_progress(spec, sessions, quiet)
        };
        let b = TrainingBench {
            runs: args.runs.clamp(1, 3),
            threads: args.threads,
            sessions: args.sessions,
            batch: args.batch,
            part_windows: args.part_windows.clone(),
        };
        let r = training::training(dir, &b, &mut fit)?;
        if !args.json {
            println!("{}", training::describe(&r));
        }
        report.insert("dekf_training".into(), r);
    }
    let cpus = allowed_cpus()?;
    let cpu = cpus.first().copied().unwrap_or(0);
    let two: Vec<usize> = cpus.iter().copied().take(2).collect();
    pin_to(&[cpu])?;
    report.insert("cpu".into(), json!(cpu));
    if args.what.contains(&BenchWhat::Dekf) {
        let r = dekf::step(args.runs)?;
        if !args.json {
            println!("{} (CPU {cpu})", dekf::describe(&r));
        }
        report.insert("dekf_step".into(), r);
    }
    if args.what.contains(&BenchWhat::Collect) {
        // Two cores: the simulated camera's frames are encoded on the second.
        pin_to(&two)?;
        report.insert("collect_cpus".into(), json!(two));
        let results = bench::collect(&options(args), dir);
        pin_to(&[cpu])?;
        let results = results?;
        if args.json {
            report.insert(
                "collect".into(),
                json!(results.iter().map(CollectMeasurement::to_json).collect::<Vec<_>>()),
            );
        } else {
            print_collect(args, &two, &results);
        }
    }
    for what in [BenchWhat::CollectLive, BenchWhat::CollectRos2] {
        if args.what.contains(&what) {
            collect_outlet(args, what, cpu, dir, &mut report)?;
        }
    }
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    }
    Ok(())
}

/// `collect-live` or `collect-ros2`: collecting with and without an outlet.
fn collect_outlet(
    args: &BenchArgs,
    what: BenchWhat,
    cpu: usize,
    dir: &std::path::Path,
    report: &mut serde_json::Map<String, serde_json::Value>,
) -> Result<()> {
    let json = args.json;
    let mut on_line = |line: String| {
        if !json {
            println!("{line}");
        }
    };
    let options = options(args);
    let (key, results) = if what == BenchWhat::CollectLive {
        on_line(bench::live::header(&options, cpu));
        ("collect_live", bench::live::measure(&options, dir, &mut on_line)?)
    } else {
        on_line(bench::ros2::header(&options, cpu));
        ("collect_ros2", bench::ros2::measure(&options, dir, &mut on_line)?)
    };
    report.insert(key.into(), json!(results));
    Ok(())
}

fn print_collect(args: &BenchArgs, cpus: &[usize], results: &[CollectMeasurement]) {
    println!(
        "collect: box, {} s of sliding cycles, pinned to CPUs {cpus:?} ({} cores, OpenCV single-threaded), median of {} runs",
        args.duration,
        cpus.len(),
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

/// The trials' options of `args`.
fn options(args: &BenchArgs) -> BenchOptions {
    BenchOptions { runs: args.runs, duration_s: args.duration }
}

fn tempfile_dir() -> Result<std::path::PathBuf> {
    let dir = std::env::temp_dir().join(format!("slidetrack-bench-{}", std::process::id()));
    std::fs::create_dir_all(&dir).with_context(|| format!("cannot create {}", dir.display()))?;
    Ok(dir)
}
