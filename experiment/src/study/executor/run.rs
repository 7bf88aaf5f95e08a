//! A whole study through an executor: its sessions (collected and labelled
//! by jobs as needed), its trainings as jobs, and the tables assembled from
//! the training jobs' results.

use std::collections::BTreeMap;
use std::path::Path;
use std::sync::atomic::AtomicBool;

use anyhow::Result;
use serde_json::Value;

use super::stages::Stages;
use super::types::{Executor, JobReport, Progress};
use super::work::train_jobs;
use crate::dataset::load;
use crate::study::{OBJECTS, Sets, StudySpec, Tables};

/// What a study produced.
pub struct StudyRun {
    /// The tables.
    pub tables: Tables,
    /// Each model's summary, in plan order.
    pub models: Vec<Value>,
    /// How each training job ran.
    pub jobs: Vec<JobReport>,
    /// How each collecting job ran (none when every object had sessions).
    pub collect_jobs: Vec<JobReport>,
    /// How each labelling job ran (none for the simulator's truth).
    pub label_jobs: Vec<JobReport>,
    /// Sessions per object (training and testing).
    pub sessions_per_object: BTreeMap<&'static str, usize>,
}

/// Runs the study `s` with `executor`, its jobs in `work_dir`.
pub fn run_study(
    s: &StudySpec,
    executor: &Executor,
    work_dir: &Path,
    stop: &AtomicBool,
    progress: &(dyn Fn(&Progress) + Sync),
) -> Result<StudyRun> {
    let stages = Stages { study: s, executor, work_dir, stop, progress };
    let sessions = stages.sessions()?;
    let mut sets = Sets::new();
    for (object, files) in &sessions.files {
        let half = files.len() / 2;
        for (test, part) in [(false, &files[..half]), (true, &files[half..])] {
            let loaded = part.iter().map(|f| load(f, Some(s.truth))).collect::<Result<Vec<_>>>()?;
            sets.insert((*object, test), loaded);
        }
    }
    let (plan, jobs) = stages.run("train", train_jobs(s, &sets), Some(&sets))?;
    let outcomes = plan.outcomes()?;
    let mut tables = Tables::default();
    for (job, o) in plan.jobs.iter().zip(&outcomes) {
        for (object, train, test) in &o.scores {
            tables.record(&job.name, object, train.clone(), test.clone());
        }
    }
    let sessions_per_object = OBJECTS.iter().map(|o| (*o, sessions.files[o].len())).collect();
    Ok(StudyRun {
        tables,
        models: outcomes.into_iter().map(|o| o.summary).collect(),
        jobs,
        collect_jobs: sessions.collected,
        label_jobs: sessions.labelled,
        sessions_per_object,
    })
}
