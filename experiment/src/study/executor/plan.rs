//! The jobs of one stage of a study in its directory of the work directory
//! (`WORK/collect`, `WORK/label`, `WORK/train`): writing them, reading them
//! back (a Slurm task), running one ([`Plan::execute`]; a Slurm task: `task.rs`) and
//! telling which are done ([`Plan::done`]).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;
use std::time::{SystemTime, UNIX_EPOCH};

use sha2::{Digest, Sha256};

use super::error::{ExecutorError, io};
use super::job::{Job, JobResult, OutputFile};
use super::work::{object, perform};
use crate::dekf_run::write_atomically;
use crate::study::{Outcome, Sets};

/// The jobs of a stage in its directory.
#[derive(Clone, Debug)]
pub struct Plan {
    /// The stage's directory.
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

/// This process's Slurm array task (`ARRAYJOB_TASK`), from the environment
/// Slurm gives a task (sbatch(1), "OUTPUT ENVIRONMENT VARIABLES").
pub fn slurm_task() -> Option<String> {
    let job = std::env::var("SLURM_ARRAY_JOB_ID").ok()?;
    let task = std::env::var("SLURM_ARRAY_TASK_ID").ok()?;
    Some(format!("{job}_{task}"))
}

/// Whether `output` is still what its job wrote.
fn still_there(output: &OutputFile) -> bool {
    if output.rewritten_later {
        output.path.is_file()
    } else {
        sha256_file(&output.path).is_ok_and(|s| s == output.sha256)
    }
}

impl Plan {
    /// `STAGE/jobs/NN-NAME.json`.
    pub fn job_path(&self, index: usize) -> PathBuf {
        self.work_dir.join("jobs").join(format!("{index:02}-{}.json", self.jobs[index].name))
    }

    /// `STAGE/results/NN-NAME.json`.
    pub fn result_path(&self, index: usize) -> PathBuf {
        self.work_dir.join("results").join(format!("{index:02}-{}.json", self.jobs[index].name))
    }

    fn job_bytes(&self, index: usize) -> Vec<u8> {
        let mut text = serde_json::to_string_pretty(&self.jobs[index]).unwrap_or_default();
        text.push('\n');
        text.into_bytes()
    }

    /// Writes the job files (those that changed) and `STAGE/plan.json`.
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
    /// file and the files it wrote are still those it wrote.
    pub fn done(&self, index: usize) -> Option<JobResult> {
        let text = std::fs::read_to_string(self.result_path(index)).ok()?;
        let result: JobResult = serde_json::from_str(&text).ok()?;
        let valid = result.name == self.jobs[index].name
            && result.job_sha256 == sha256(&self.job_bytes(index))
            && !result.outputs.is_empty()
            && result.outputs.iter().all(still_there);
        valid.then_some(result)
    }

    /// The jobs without a valid result.
    pub fn pending(&self) -> Vec<usize> {
        (0..self.jobs.len()).filter(|i| self.done(*i).is_none()).collect()
    }

    /// The outcomes of every (training) job, from their results, in plan order.
    pub fn outcomes(&self) -> Result<Vec<Outcome>, ExecutorError> {
        (0..self.jobs.len())
            .map(|index| {
                let path = self.result_path(index);
                let job_error = |message| ExecutorError::Job { name: self.jobs[index].name.clone(), message };
                let result = self
                    .done(index)
                    .ok_or_else(|| job_error(format!("no valid result in {}", path.display())))?;
                let scores = result
                    .scores
                    .into_iter()
                    .map(|r| {
                        Ok((
                            object(&r.object).map_err(|e| job_error(format!("{path:?}: {e}")))?,
                            r.train,
                            r.test,
                        ))
                    })
                    .collect::<Result<Vec<_>, ExecutorError>>()?;
                Ok(Outcome { summary: result.summary, scores })
            })
            .collect()
    }

    /// Runs job `index` (a training job on `sets` when given, else on its
    /// sessions loaded from their files) and writes its result.
    pub fn execute(
        &self,
        index: usize,
        sets: Option<&Sets>,
        stop: &AtomicBool,
    ) -> Result<JobResult, ExecutorError> {
        let job = &self.jobs[index];
        let failed =
            |e: anyhow::Error| ExecutorError::Job { name: job.name.clone(), message: format!("{e:#}") };
        let started_unix_s = now_unix_s();
        let performed = perform(job, sets, stop).map_err(failed)?;
        let outputs = performed
            .outputs
            .into_iter()
            .map(|(path, rewritten_later)| {
                Ok(OutputFile { sha256: sha256_file(&path)?, path, rewritten_later })
            })
            .collect::<Result<Vec<_>, ExecutorError>>()?;
        let result = JobResult {
            name: job.name.clone(),
            job_sha256: sha256(&self.job_bytes(index)),
            outputs,
            summary: performed.summary,
            scores: performed.scores,
            host: host_name(),
            slurm_task: slurm_task(),
            started_unix_s,
            finished_unix_s: now_unix_s(),
        };
        self.write_result(index, &result)?;
        Ok(result)
    }

    /// Writes `result` as job `index`'s.
    fn write_result(&self, index: usize, result: &JobResult) -> Result<(), ExecutorError> {
        let text = serde_json::to_string_pretty(result).map_err(|e| ExecutorError::Job {
            name: self.jobs[index].name.clone(),
            message: e.to_string(),
        })?;
        write(&self.result_path(index), format!("{text}\n").as_bytes())
    }
}

#[cfg(test)]
mod tests {
    use serde_json::json;

    use super::*;
    use crate::dataset::TruthSource;
    use crate::dekf_run::Scores;
    use crate::protocol::Protocol;
    use crate::study::executor::job::{ScoreRow, Work};
    use crate::study::{StudySpec, Tables};

    /// A training job whose model diverged (NaN scores) is done: its result
    /// reads back with the NaN, and the tables show NaN. (The result files
    /// once wrote NaN as `null`, which did not read back: the job looked
    /// unfinished and was run again forever.)
    #[test]
    fn a_finished_job_with_a_nan_score_is_done_and_tabled_as_nan() {
        let dir = std::env::temp_dir().join(format!("slidetrack-plan-nan-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let study = StudySpec {
            sessions: dir.join("sessions"),
            out: dir.join("out"),
            collect: 2,
            duration_s: 1.0,
            schedule: Vec::new(),
            protocol: Protocol::Default,
            truth: TruthSource::Sim,
            seed: 1,
            threads: 1,
        };
        let job = Job {
            index: 0,
            name: "box-xy".into(),
            threads: 1,
            study,
            work: Work::Train { sets: Vec::new() },
        };
        let plan = Plan { work_dir: dir.join("work/train"), jobs: vec![job] };
        plan.write().expect("plan written");
        let model = dir.join("out/models/box-xy.safetensors");
        std::fs::create_dir_all(model.parent().expect("parent")).expect("models directory");
        std::fs::write(&model, b"model").expect("model written");
        let nan = Scores { position_rmse_cm: f64::NAN, velocity_rmse_cmps: 2.5, ..Scores::default() };
        let result = JobResult {
            name: "box-xy".into(),
            job_sha256: sha256(&plan.job_bytes(0)),
            outputs: vec![OutputFile {
                sha256: sha256(b"model"),
                path: model.clone(),
                rewritten_later: false,
            }],
            summary: json!({"name": "box-xy"}),
            scores: vec![ScoreRow { object: "box".into(), train: None, test: nan }],
            host: "h".into(),
            slurm_task: None,
            started_unix_s: 1.0,
            finished_unix_s: 2.0,
        };
        plan.write_result(0, &result).expect("result written");
        assert!(plan.done(0).is_some(), "a NaN score must not make the job look unfinished");
        assert!(plan.pending().is_empty());
        let outcome = plan.outcomes().expect("outcomes").remove(0);
        let (object, _, test) = &outcome.scores[0];
        assert!(test.position_rmse_cm.is_nan() && test.velocity_rmse_cmps == 2.5);
        let mut tables = Tables::default();
        tables.record("box-xy", object, None, test.clone());
        let md = tables.markdown(&json!({}));
        assert!(md.lines().any(|l| l.starts_with("| box | - | NaN |")), "{md}");
        // A changed model file invalidates the result.
        std::fs::write(&model, b"other").expect("model rewritten");
        assert!(plan.done(0).is_none());
        let _ = std::fs::remove_dir_all(&dir);
    }
}
