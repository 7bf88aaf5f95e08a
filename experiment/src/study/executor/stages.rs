//! The stages of a study, each a plan of jobs run by the study's executor
//! in its own directory of the work directory: `WORK/collect` (one job per
//! trial of each object without sessions), `WORK/label` (one job per
//! session, when the study's truth is a labelled one) and `WORK/train`
//! (one job per model). A stage starts when the one before it is done.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};

use anyhow::{Context as _, Result, bail};

use super::error::ExecutorError;
use super::job::{Job, Work};
use super::local::run_local;
use super::plan::Plan;
use super::slurm::run_slurm;
use super::types::{Executor, JobReport, Progress};
use super::work::{collect_jobs, label_jobs};
use crate::dataset::expand;
use crate::protocol::Protocol;
use crate::study::{OBJECTS, Sets, StudySpec, has_topic, object_of};

/// What the stages share: the study, where and how its jobs run.
pub struct Stages<'a> {
    /// The study.
    pub study: &'a StudySpec,
    /// Where its jobs run.
    pub executor: &'a Executor,
    /// The work directory.
    pub work_dir: &'a Path,
    /// Set on Ctrl-C.
    pub stop: &'a AtomicBool,
    /// Called as jobs finish.
    pub progress: &'a (dyn Fn(&Progress) + Sync),
}

/// The study's sessions per object, and the reports of the jobs that
/// collected and labelled them.
pub struct Sessions {
    /// Each object's session files, sorted by name.
    pub files: BTreeMap<&'static str, Vec<PathBuf>>,
    /// The collecting jobs.
    pub collected: Vec<JobReport>,
    /// The labelling jobs.
    pub labelled: Vec<JobReport>,
}

/// The objects a collection of an earlier run of the study planned
/// (`WORK/collect/plan.json`): collected again until complete, even though
/// some of their sessions are there now.
fn collecting_before(dir: &Path) -> BTreeSet<String> {
    let Ok(plan) = Plan::read(dir) else { return BTreeSet::new() };
    plan.jobs
        .into_iter()
        .filter_map(|j| match j.work {
            Work::Collect { object, .. } => Some(object),
            _ => None,
        })
        .collect()
}

impl Stages<'_> {
    /// Runs `jobs` as stage `name` (in `WORK/name`); a training stage on
    /// `sets` when the local executor has them loaded.
    pub fn run(
        &self,
        name: &str,
        jobs: Vec<Job>,
        sets: Option<&Sets>,
    ) -> Result<(Plan, Vec<JobReport>), ExecutorError> {
        let plan = Plan { work_dir: self.work_dir.join(name), jobs };
        plan.write()?;
        if plan.jobs.is_empty() {
            return Ok((plan, Vec::new()));
        }
        let progress = |p: &Progress| (self.progress)(&Progress { stage: name.to_string(), ..p.clone() });
        let reports = match self.executor {
            Executor::Local => run_local(&plan, sets, self.study.threads, self.stop, &progress)?,
            Executor::Slurm(config) => {
                self.record_no_ops(&plan)?;
                run_slurm(&plan, config, self.stop, &progress)?
            }
        };
        Ok((plan, reports))
    }

    /// Runs here the labelling jobs whose session already has the study's
    /// truth: they only record it, which is not worth a Slurm task.
    fn record_no_ops(&self, plan: &Plan) -> Result<(), ExecutorError> {
        for index in plan.pending() {
            if let Work::Label { session, .. } = &plan.jobs[index].work
                && has_topic(session, self.study.truth.topic()).unwrap_or(false)
            {
                plan.execute(index, None, self.stop)?;
            }
        }
        Ok(())
    }

    /// The sessions of every object: those in the study's sessions
    /// directory, collected where an object has none, labelled where the
    /// study's truth is a labelled one.
    pub fn sessions(&self) -> Result<Sessions> {
        let s = self.study;
        std::fs::create_dir_all(&s.sessions)
            .with_context(|| format!("cannot create {}", s.sessions.display()))?;
        let mut by_object: BTreeMap<String, Vec<PathBuf>> = BTreeMap::new();
        if let Ok(files) = expand(std::slice::from_ref(&s.sessions)) {
            for f in files {
                by_object.entry(object_of(&f)?).or_default().push(f);
            }
        }
        let before = collecting_before(&self.work_dir.join("collect"));
        let to_collect: Vec<&str> = OBJECTS
            .iter()
            .copied()
            .filter(|o| before.contains(*o) || by_object.get(*o).is_none_or(Vec::is_empty))
            .collect();
        for o in &to_collect {
            eprintln!("{o}: collecting {} sessions into {}", s.collect, s.sessions.display());
        }
        let (plan, collected) = self.run("collect", collect_jobs(s, &to_collect), None)?;
        for job in &plan.jobs {
            if let Work::Collect { object, session, .. } = &job.work {
                by_object.entry(object.clone()).or_default().push(session.clone());
            }
        }
        let mut files = BTreeMap::new();
        for object in OBJECTS {
            let mut f = by_object.remove(object).unwrap_or_default();
            if to_collect.contains(&object) {
                f.retain(|p| {
                    plan.jobs.iter().any(|j| matches!(&j.work, Work::Collect { session, .. } if session == p))
                });
            }
            f.sort();
            f.dedup();
            if f.len() < 2 {
                bail!(
                    "{object}: {} session(s) in {}; the study needs at least 2",
                    f.len(),
                    s.sessions.display()
                );
            }
            files.insert(object, f);
        }
        let labelled = match Protocol::labelling(s.truth) {
            Some(protocol) => {
                let all: Vec<PathBuf> = files.values().flatten().cloned().collect();
                self.run("label", label_jobs(s, protocol, &all), None)?.1
            }
            None => Vec::new(),
        };
        if self.stop.load(Ordering::SeqCst) {
            bail!("interrupted; run the same command again to resume");
        }
        Ok(Sessions { files, collected, labelled })
    }
}
