//! Data sets of simulated sessions for `demo` and `study`: trials collected
//! in parallel (one trial per worker thread) and labelled with the ArUco
//! ground truth.

use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

use anyhow::{Context, Result, anyhow};
use slidetrack_calibration::ground_truth::{AxisSource, default_params};
use slidetrack_calibration::label::{LabelOptions, label_session};
use slidetrack_sim::ObjectConfig;

use crate::rig_config::RigConfig;
use crate::trial::{TrialReport, TrialSpec, prepare_out_dir, run_sim_trial, session_file_name};

/// A set of simulated trials of one object.
#[derive(Clone, Debug)]
pub struct DataSpec {
    /// Object name (box, bottle, mustard) or path.
    pub object: String,
    /// Seed of the simulated rig.
    pub seed: u64,
    /// Trial numbers.
    pub trials: std::ops::Range<u32>,
    /// Duration of the sliding cycles (s).
    pub duration_s: f64,
    /// Render the camera and detect the marker (needed for the ground truth).
    pub camera: bool,
}

/// Runs `jobs` on `threads` named worker threads, each job once; results in job order.
pub fn parallel<T: Send, J: Sync>(
    name: &str,
    jobs: &[J],
    threads: usize,
    stop: &AtomicBool,
    work: impl Fn(&J) -> Result<T> + Sync,
) -> Result<Vec<T>> {
    let next = AtomicUsize::new(0);
    let results: Mutex<Vec<Option<Result<T>>>> = Mutex::new((0..jobs.len()).map(|_| None).collect());
    let worker = || {
        loop {
            let i = next.fetch_add(1, Ordering::SeqCst);
            if i >= jobs.len() || stop.load(Ordering::SeqCst) {
                break;
            }
            let r = work(&jobs[i]);
            let failed = r.is_err();
            if let Ok(mut all) = results.lock() {
                all[i] = Some(r);
            }
            if failed {
                // Let the other workers finish their job, but start no new one.
                next.store(jobs.len(), Ordering::SeqCst);
            }
        }
    };
    std::thread::scope(|scope| -> Result<()> {
        for k in 0..threads.clamp(1, jobs.len().max(1)) {
            std::thread::Builder::new()
                .name(format!("{name}-{k}"))
                .spawn_scoped(scope, worker)
                .context("cannot start a worker thread")?;
        }
        Ok(())
    })?;
    let results = results.into_inner().map_err(|_| anyhow!("a {name} worker panicked"))?;
    let mut out = Vec::with_capacity(jobs.len());
    for r in results {
        match r {
            Some(r) => out.push(r?),
            None => anyhow::bail!("{name}: interrupted"),
        }
    }
    Ok(out)
}

/// Collects the trials of `spec` into `dir`, `threads` at a time, and calls
/// `done` after each. A session file that exists already is kept (reported
/// as `None`), so an interrupted data collection resumes where it stopped.
pub fn collect(
    spec: &DataSpec,
    dir: &Path,
    threads: usize,
    stop: &AtomicBool,
    done: &(dyn Fn(&Path, Option<&TrialReport>) + Sync),
) -> Result<Vec<PathBuf>> {
    prepare_out_dir(dir)?;
    let object = ObjectConfig::load(&spec.object)?;
    let rig = RigConfig::default();
    let trials: Vec<u32> = spec.trials.clone().collect();
    parallel("collect", &trials, threads, stop, |&trial| {
        let path = dir.join(session_file_name(&object.name, spec.seed, trial));
        if path.exists() {
            done(&path, None);
            return Ok(path);
        }
        let partial = path.with_extension("mcap.partial");
        let t = TrialSpec {
            rig: &rig,
            object: &object,
            seed: spec.seed,
            trial,
            duration_s: spec.duration_s,
            camera: spec.camera,
            realtime: false,
            overwrite: true,
            path: partial.clone(),
        };
        let mut report = run_sim_trial(&t, stop, &mut |_| {})?;
        if let Some(reason) = &report.outcome.abort {
            anyhow::bail!("{}: trial aborted: {reason}", path.display());
        }
        std::fs::rename(&partial, &path).with_context(|| format!("cannot write {}", path.display()))?;
        report.path.clone_from(&path);
        done(&path, Some(&report));
        Ok(path)
    })
}

/// Labels `files` with the default ground-truth parameters, `threads` at a time.
pub fn label(files: &[PathBuf], threads: usize, stop: &AtomicBool) -> Result<()> {
    let options =
        LabelOptions { params: default_params(), axis: AxisSource::Recorded, recover: false, dry_run: false };
    parallel("label", files, threads, stop, |f| {
        label_session(f, &options).with_context(|| format!("cannot label {}", f.display()))?;
        Ok(())
    })?;
    Ok(())
}

/// Worker threads to use: `requested`, or every core when 0.
pub fn threads(requested: usize) -> usize {
    if requested > 0 {
        requested
    } else {
        std::thread::available_parallelism().map_or(1, std::num::NonZero::get)
    }
}
