//! The local executor: the jobs without a result, `threads` at a time, on
//! this machine (training jobs on the sets the study has already loaded).

use std::sync::atomic::AtomicBool;
use std::sync::atomic::{AtomicUsize, Ordering};

use super::error::ExecutorError;
use super::plan::Plan;
use super::types::{JobReport, Progress};
use crate::pipeline::parallel;
use crate::study::Sets;

/// Runs the jobs of `plan` that have no valid result, `threads` at a time
/// (training jobs on `sets` when given, else on their sessions' files),
/// calling `progress` as they finish; returns every job's report.
pub fn run_local(
    plan: &Plan,
    sets: Option<&Sets>,
    threads: usize,
    stop: &AtomicBool,
    progress: &(dyn Fn(&Progress) + Sync),
) -> Result<Vec<JobReport>, ExecutorError> {
    let pending = plan.pending();
    let done = AtomicUsize::new(plan.jobs.len() - pending.len());
    let report = |done: usize| {
        progress(&Progress {
            jobs: plan.jobs.len(),
            done,
            running: threads.min(plan.jobs.len() - done),
            ..Progress::default()
        })
    };
    report(done.load(Ordering::SeqCst));
    parallel("job", &pending, threads, stop, |&index| {
        let r = plan.execute(index, sets, stop);
        report(done.fetch_add(1, Ordering::SeqCst) + 1);
        Ok(r?)
    })
    .map_err(|e| match e.downcast::<ExecutorError>() {
        Ok(e) => e,
        Err(_) if stop.load(Ordering::SeqCst) => ExecutorError::Interrupted { left: String::new() },
        Err(e) => ExecutorError::Job { name: "job".into(), message: format!("{e:#}") },
    })?;
    Ok((0..plan.jobs.len())
        .map(|index| {
            let result = plan.done(index);
            JobReport {
                index,
                name: plan.jobs[index].name.clone(),
                reused: !pending.contains(&index),
                attempts: u32::from(pending.contains(&index)),
                slurm_tasks: Vec::new(),
                ran_in: result.as_ref().and_then(|r| r.slurm_task.clone()),
                host: result.as_ref().map_or_else(String::new, |r| r.host.clone()),
                started_unix_s: result.as_ref().map_or(f64::NAN, |r| r.started_unix_s),
                finished_unix_s: result.as_ref().map_or(f64::NAN, |r| r.finished_unix_s),
            }
        })
        .collect())
}
