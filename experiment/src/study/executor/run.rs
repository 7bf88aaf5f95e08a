//! A whole study through an executor: its data (collected and labelled
//! here, as needed), its plan in the work directory, the jobs run here or on
//! Slurm, and the tables assembled from the jobs' results.

use std::collections::BTreeMap;
use std::path::Path;
use std::sync::atomic::AtomicBool;

use anyhow::Result;
use serde_json::Value;

use super::job::Plan;
use super::local::run_local;
use super::slurm::run_slurm;
use super::types::{JobReport, Progress, SlurmConfig};
use crate::study::{OBJECTS, StudySpec, Tables, data};

/// Where the study's jobs run.
#[derive(Clone, Debug)]
pub enum Executor {
    /// Here, `StudySpec::threads` at a time.
    Local,
    /// As a Slurm job array.
    Slurm(SlurmConfig),
}

/// What a study produced.
pub struct StudyRun {
    /// The tables.
    pub tables: Tables,
    /// Each model's summary, in plan order.
    pub models: Vec<Value>,
    /// How each job ran.
    pub jobs: Vec<JobReport>,
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
    let sets = data(s, stop)?;
    let plan = Plan::new(s, &sets, work_dir);
    plan.write()?;
    let jobs = match executor {
        Executor::Local => run_local(&plan, &sets, s.threads, stop, progress)?,
        Executor::Slurm(config) => run_slurm(&plan, config, stop, progress)?,
    };
    let outcomes = plan.outcomes()?;
    let mut tables = Tables::default();
    for (job, o) in plan.jobs.iter().zip(&outcomes) {
        for (object, train, test) in &o.scores {
            tables.record(&job.name, object, train.clone(), test.clone());
        }
    }
    let sessions_per_object =
        OBJECTS.iter().map(|o| (*o, sets[&(*o, false)].len() + sets[&(*o, true)].len())).collect();
    Ok(StudyRun {
        tables,
        models: outcomes.into_iter().map(|o| o.summary).collect(),
        jobs,
        sessions_per_object,
    })
}
