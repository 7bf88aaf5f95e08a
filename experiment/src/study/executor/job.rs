//! The study's jobs: one per model, written to `WORK/jobs/`, run by
//! [`run_job`] (anywhere that sees the work directory and the sessions),
//! each leaving a validated result in `WORK/results/`.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::{SystemTime, UNIX_EPOCH};

use serde::{Deserialize, Serialize};
use serde_json::Value;
use sha2::{Digest, Sha256};

use super::error::{ExecutorError, io};
use crate::dataset::{SessionData, load};
use crate::dekf_run::{Scores, write_atomically};
use crate::linear_baseline::path_for;
use crate::study::{ModelSpec, OBJECTS, Outcome, Sets, StudySpec, models, sets_of, train_and_score};

/// The session files of one object's training or testing set.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SetFiles {
    /// The object.
    pub object: String,
    /// The testing set (`true`) or the training set.
    pub testing: bool,
    /// Its sessions, in the order the study reads them.
    pub files: Vec<PathBuf>,
}

/// One job: train one model of the study and score it.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Job {
    /// Its index in the plan.
    pub index: usize,
    /// The model it trains ([`models`]).
    pub name: String,
    /// Cores it uses.
    pub threads: usize,
    /// The study's settings (`threads` 1: results do not depend on it).
    pub study: StudySpec,
    /// The sets it reads.
    pub sets: Vec<SetFiles>,
}

/// One scored object of a result.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct ScoreRow {
    /// The tested object.
    pub object: String,
    /// Scores on its training set (Table 6.1 only).
    pub train: Option<Scores>,
    /// Scores on its testing set.
    pub test: Scores,
}

/// What a job leaves in `WORK/results/`: valid while the job file and the
/// model files still have the recorded SHA-256.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct JobResult {
    /// The job's name.
    pub name: String,
    /// SHA-256 of the job file it ran.
    pub job_sha256: String,
    /// SHA-256 of the model it wrote.
    pub model_sha256: String,
    /// SHA-256 of the linear baseline it wrote beside the model.
    pub linear_sha256: String,
    /// The model's summary in `tables.json`.
    pub summary: Value,
    /// Its scores.
    pub scores: Vec<ScoreRow>,
    /// Host that ran it.
    pub host: String,
    /// When it started (s since the Unix epoch).
    pub started_unix_s: f64,
    /// When it finished (s since the Unix epoch).
    pub finished_unix_s: f64,
}

/// The jobs of a study in its work directory.
#[derive(Clone, Debug)]
pub struct Plan {
    /// The work directory.
    pub work_dir: PathBuf,
    /// The jobs, by index.
    pub jobs: Vec<Job>,
}

/// SHA-256 of `bytes` in hex.
pub fn sha256(bytes: &[u8]) -> String {
    Sha256::digest(bytes).iter().map(|b| format!("{b:02x}")).collect()
}

fn sha256_file(path: &Path) -> Result<String, ExecutorError> {
    Ok(sha256(&std::fs::read(path).map_err(io(path))?))
}

fn write(path: &Path, bytes: &[u8]) -> Result<(), ExecutorError> {
    write_atomically(path, bytes)
        .map_err(|e| ExecutorError::Io { path: path.into(), source: std::io::Error::other(format!("{e:#}")) })
}

fn now_unix_s() -> f64 {
    SystemTime::now().duration_since(UNIX_EPOCH).map_or(0.0, |d| d.as_secs_f64())
}

/// This machine's host name.
pub fn host_name() -> String {
    std::fs::read_to_string("/proc/sys/kernel/hostname")
        .map(|h| h.trim().to_string())
        .unwrap_or_else(|_| "unknown".into())
}

impl Job {
    /// The model's file.
    pub fn model_path(&self) -> PathBuf {
        self.study.out.join("models").join(format!("{}.safetensors", self.name))
    }

    /// The model of [`models`] it trains.
    fn model(&self, path: &Path) -> Result<ModelSpec, ExecutorError> {
        models().into_iter().find(|m| m.name == self.name).ok_or_else(|| ExecutorError::Parse {
            path: path.into(),
            message: format!("no model `{}` in the study", self.name),
        })
    }
}

/// The object of [`OBJECTS`] named `name`.
fn object(name: &str, path: &Path) -> Result<&'static str, ExecutorError> {
    OBJECTS.iter().copied().find(|o| *o == name).ok_or_else(|| ExecutorError::Parse {
        path: path.into(),
        message: format!("no object `{name}` in the study"),
    })
}

impl Plan {
    /// The plan of `study` on `sets`: one job per model of [`models`].
    pub fn new(study: &StudySpec, sets: &Sets, work_dir: &Path) -> Plan {
        let mut settings = study.clone();
        settings.threads = 1;
        let jobs = models()
            .iter()
            .enumerate()
            .map(|(index, spec)| Job {
                index,
                name: spec.name.clone(),
                threads: 1,
                study: settings.clone(),
                sets: sets_of(spec)
                    .into_iter()
                    .map(|(object, testing)| SetFiles {
                        object: object.into(),
                        testing,
                        files: sets[&(object, testing)].iter().map(|d| d.path.clone()).collect(),
                    })
                    .collect(),
            })
            .collect();
        Plan { work_dir: work_dir.into(), jobs }
    }

    /// `WORK/jobs/NN-NAME.json`.
    pub fn job_path(&self, index: usize) -> PathBuf {
        self.work_dir.join("jobs").join(format!("{index:02}-{}.json", self.jobs[index].name))
    }

    /// `WORK/results/NN-NAME.json`.
    pub fn result_path(&self, index: usize) -> PathBuf {
        self.work_dir.join("results").join(format!("{index:02}-{}.json", self.jobs[index].name))
    }

    fn job_bytes(&self, index: usize) -> Vec<u8> {
        let mut text = serde_json::to_string_pretty(&self.jobs[index]).unwrap_or_default();
        text.push('\n');
        text.into_bytes()
    }

    /// Writes the job files (those that changed) and `WORK/plan.json`.
    pub fn write(&self) -> Result<(), ExecutorError> {
        for index in 0..self.jobs.len() {
            let (path, bytes) = (self.job_path(index), self.job_bytes(index));
            if std::fs::read(&path).ok().as_deref() != Some(&bytes[..]) {
                write(&path, &bytes)?;
            }
        }
        let names: Vec<String> = (0..self.jobs.len())
            .map(|i| {
                self.job_path(i).file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default()
            })
            .collect();
        let plan = serde_json::json!({ "jobs": names });
        write(&self.work_dir.join("plan.json"), format!("{plan:#}\n").as_bytes())
    }

    /// The plan written in `work_dir` by [`Plan::write`].
    pub fn read(work_dir: &Path) -> Result<Plan, ExecutorError> {
        let plan_path = work_dir.join("plan.json");
        let text = std::fs::read_to_string(&plan_path).map_err(io(&plan_path))?;
        let parse = |path: &Path, e: serde_json::Error| ExecutorError::Parse {
            path: path.into(),
            message: e.to_string(),
        };
        let plan: BTreeMap<String, Vec<String>> =
            serde_json::from_str(&text).map_err(|e| parse(&plan_path, e))?;
        let mut jobs = Vec::new();
        for name in plan.get("jobs").into_iter().flatten() {
            let path = work_dir.join("jobs").join(name);
            let text = std::fs::read_to_string(&path).map_err(io(&path))?;
            jobs.push(serde_json::from_str::<Job>(&text).map_err(|e| parse(&path, e))?);
        }
        Ok(Plan { work_dir: work_dir.into(), jobs })
    }

    /// The result of job `index` if it exists and is valid: it ran this job
    /// file and the model files it names are still those it wrote.
    pub fn done(&self, index: usize) -> Option<JobResult> {
        let text = std::fs::read_to_string(self.result_path(index)).ok()?;
        let result: JobResult = serde_json::from_str(&text).ok()?;
        let model = self.jobs[index].model_path();
        let valid = result.name == self.jobs[index].name
            && result.job_sha256 == sha256(&self.job_bytes(index))
            && sha256_file(&model).ok()? == result.model_sha256
            && sha256_file(&path_for(&model)).ok()? == result.linear_sha256;
        valid.then_some(result)
    }

    /// The jobs without a valid result.
    pub fn pending(&self) -> Vec<usize> {
        (0..self.jobs.len()).filter(|i| self.done(*i).is_none()).collect()
    }

    /// The outcomes of every job, from their results, in plan order.
    pub fn outcomes(&self) -> Result<Vec<Outcome>, ExecutorError> {
        (0..self.jobs.len())
            .map(|index| {
                let path = self.result_path(index);
                let result = self.done(index).ok_or_else(|| ExecutorError::Job {
                    name: self.jobs[index].name.clone(),
                    message: format!("no valid result in {}", path.display()),
                })?;
                let scores = result
                    .scores
                    .into_iter()
                    .map(|r| Ok((object(&r.object, &path)?, r.train, r.test)))
                    .collect::<Result<Vec<_>, ExecutorError>>()?;
                Ok(Outcome { summary: result.summary, scores })
            })
            .collect()
    }

    /// Runs job `index` on `sets` (which hold at least the job's sets) and
    /// writes its result.
    pub fn execute(&self, index: usize, sets: &Sets) -> Result<JobResult, ExecutorError> {
        let job = &self.jobs[index];
        let failed =
            |e: anyhow::Error| ExecutorError::Job { name: job.name.clone(), message: format!("{e:#}") };
        let started_unix_s = now_unix_s();
        let spec = job.model(&self.job_path(index))?;
        let outcome = train_and_score(&spec, sets, &job.study).map_err(failed)?;
        let model = job.model_path();
        let result = JobResult {
            name: job.name.clone(),
            job_sha256: sha256(&self.job_bytes(index)),
            model_sha256: sha256_file(&model)?,
            linear_sha256: sha256_file(&path_for(&model))?,
            summary: outcome.summary,
            scores: outcome
                .scores
                .into_iter()
                .map(|(object, train, test)| ScoreRow { object: object.into(), train, test })
                .collect(),
            host: host_name(),
            started_unix_s,
            finished_unix_s: now_unix_s(),
        };
        let text = serde_json::to_string_pretty(&result)
            .map_err(|e| ExecutorError::Job { name: job.name.clone(), message: e.to_string() })?;
        write(&self.result_path(index), format!("{text}\n").as_bytes())?;
        Ok(result)
    }
}

/// Runs job `index` of the plan in `work_dir`, loading its sessions from
/// their files (what a Slurm task does: `slidetrack study-job`).
pub fn run_job(work_dir: &Path, index: usize) -> Result<JobResult, ExecutorError> {
    let plan = Plan::read(work_dir)?;
    let job = plan.jobs.get(index).ok_or_else(|| ExecutorError::NoSuchJob {
        work_dir: work_dir.into(),
        index,
        jobs: plan.jobs.len(),
    })?;
    let path = plan.job_path(index);
    let mut sets = Sets::new();
    for set in &job.sets {
        let loaded = set
            .files
            .iter()
            .map(|f| load(f, Some(job.study.truth)))
            .collect::<anyhow::Result<Vec<SessionData>>>()
            .map_err(|e| ExecutorError::Job { name: job.name.clone(), message: format!("{e:#}") })?;
        sets.insert((object(&set.object, &path)?, set.testing), loaded);
    }
    plan.execute(index, &sets)
}
