//! Data sets of simulated sessions for `demo` and `study`: trials collected
//! in parallel (one trial per worker thread, on a rayon pool) and labelled
//! with the ArUco ground truth.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};

use anyhow::{Context, Result, bail};
use rayon::prelude::*;
use slidetrack_calibration::ground_truth::AxisSource;
use slidetrack_calibration::label::{LabelOptions, Tuning, label_session};
use slidetrack_sim::ObjectConfig;

use crate::protocol::Protocol;
use crate::rig::TrialSpec;
use crate::rig_config::RigConfig;
use crate::trial::{TrialReport, prepare_out_dir, run_sim_trial, session_file_name};

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

/// Runs `jobs` on a pool of `threads` worker threads named `name-K`, each
/// job once; results in job order. After a failure or once `stop` is set, no
/// new job starts (the running ones finish); the first error is returned.
pub fn parallel<T: Send, J: Sync>(
    name: &str,
    jobs: &[J],
    threads: usize,
    stop: &AtomicBool,
    work: impl Fn(&J) -> Result<T> + Sync,
) -> Result<Vec<T>> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads.clamp(1, jobs.len().max(1)))
        .thread_name({
            let name = name.to_string();
            move |k| format!("{name}-{k}")
        })
        .build()
        .context("cannot start the worker threads")?;
    let failed = AtomicBool::new(false);
    let results: Vec<Option<Result<T>>> = pool.install(|| {
        jobs.par_iter()
            .with_max_len(1)
            .map(|job| {
                if stop.load(Ordering::SeqCst) || failed.load(Ordering::SeqCst) {
                    return None;
                }
                let r = work(job);
                if r.is_err() {
                    failed.store(true, Ordering::SeqCst);
                }
                Some(r)
            })
            .collect()
    });
    let mut out = Vec::with_capacity(jobs.len());
    let mut interrupted = false;
    for r in results {
        match r {
            Some(Err(e)) => return Err(e),
            Some(Ok(v)) => out.push(v),
            None => interrupted = true,
        }
    }
    if interrupted {
        bail!("{name}: interrupted");
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
            live: None,
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

/// Labels `files` with the ground truth of `protocol` (its smoother's
/// parameters, into its own channels), `threads` at a time.
pub fn label(files: &[PathBuf], protocol: Protocol, threads: usize, stop: &AtomicBool) -> Result<()> {
    let options = LabelOptions {
        params: protocol.label_params(),
        axis: AxisSource::Recorded,
        hand: None,
        recover: false,
        dry_run: false,
        tuning: Tuning::Off,
        slot: protocol.slot(),
        // The sliding ground truth only: the demo and the study train the
        // thesis's state.
        in_hand: None,
        in_hand_joint: None,
    };
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

#[cfg(test)]
mod tests {
    use std::sync::atomic::AtomicUsize;

    use super::*;

    #[test]
    fn results_come_in_job_order_on_named_threads() {
        let jobs: Vec<u32> = (0..20).collect();
        let out = parallel("square", &jobs, 3, &AtomicBool::new(false), |&j| {
            let name = std::thread::current().name().unwrap_or_default().to_string();
            assert!(name.starts_with("square-"), "{name}");
            Ok(j * j)
        })
        .unwrap();
        assert_eq!(out, jobs.iter().map(|j| j * j).collect::<Vec<_>>());
    }

    #[test]
    fn a_failure_is_returned_and_stops_new_jobs() {
        // On one worker the jobs run in order: none may start after job 3 fails.
        let started = AtomicUsize::new(0);
        let jobs: Vec<u32> = (0..20).collect();
        let e = parallel("fail", &jobs, 1, &AtomicBool::new(false), |&j| {
            started.fetch_add(1, Ordering::SeqCst);
            if j == 3 { bail!("job {j} failed") } else { Ok(j) }
        })
        .unwrap_err();
        assert_eq!(e.to_string(), "job 3 failed");
        assert_eq!(started.load(Ordering::SeqCst), 4, "jobs kept starting after the failure");
        // On several workers the failure comes back, whichever job fails.
        let e = parallel("fail", &jobs, 3, &AtomicBool::new(false), |&j| {
            if j == 17 { bail!("job {j} failed") } else { Ok(j) }
        })
        .unwrap_err();
        assert_eq!(e.to_string(), "job 17 failed");
    }

    #[test]
    fn a_stop_before_the_start_runs_nothing() {
        let e = parallel("stopped", &[1, 2, 3], 2, &AtomicBool::new(true), |&j: &i32| Ok(j)).unwrap_err();
        assert!(e.to_string().contains("interrupted"), "{e}");
    }
}
