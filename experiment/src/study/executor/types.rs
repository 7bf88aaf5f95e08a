//! What the executors share: the Slurm settings, progress and the per-job report.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use super::error::{ExecutorError, io};

/// Settings of the Slurm executor, from a TOML file (`study --slurm FILE`).
/// Every field is optional.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SlurmConfig {
    /// `--partition` of the array jobs.
    pub partition: Option<String>,
    /// `--account` to charge.
    pub account: Option<String>,
    /// `--time`: the time limit of one task (`MM`, `HH:MM:SS`, `D-HH`, ...).
    pub time: Option<String>,
    /// `--mem`: the memory of one task (`2G`).
    pub mem: Option<String>,
    /// Further `sbatch` options, one per entry (`--qos=short`).
    #[serde(default)]
    pub sbatch_options: Vec<String>,
    /// Submissions of a failed or cancelled task after its first (default 2).
    #[serde(default = "default_retries")]
    pub retries: u32,
    /// Seconds between two looks at the queue (default 1).
    #[serde(default = "default_poll_s")]
    pub poll_s: f64,
    /// Seconds a task that left the queue may take to show its result file
    /// (a shared file system's delay) before it counts as failed (default 10).
    #[serde(default = "default_grace_s")]
    pub result_grace_s: f64,
    /// At most this many tasks of an array at once (`--array=...%N`).
    pub max_running: Option<u32>,
    /// Whether a task, after its own job, runs the stage's other jobs that
    /// no task has taken yet (default true): the cores stay busy while the
    /// cluster is slow to start the next task. See `task.rs`.
    #[serde(default = "default_steal")]
    pub steal: bool,
    /// The slidetrack binary the tasks run (default: this one); it must be
    /// reachable at this path on the compute nodes.
    pub binary: Option<PathBuf>,
}

fn default_retries() -> u32 {
    2
}

fn default_steal() -> bool {
    true
}

fn default_poll_s() -> f64 {
    1.0
}

fn default_grace_s() -> f64 {
    10.0
}

impl Default for SlurmConfig {
    fn default() -> SlurmConfig {
        SlurmConfig {
            partition: None,
            account: None,
            time: None,
            mem: None,
            sbatch_options: Vec::new(),
            retries: default_retries(),
            poll_s: default_poll_s(),
            result_grace_s: default_grace_s(),
            max_running: None,
            steal: default_steal(),
            binary: None,
        }
    }
}

impl SlurmConfig {
    /// Reads the settings from the TOML file `path`.
    pub fn read(path: &Path) -> Result<SlurmConfig, ExecutorError> {
        let text = std::fs::read_to_string(path).map_err(io(path))?;
        let config: SlurmConfig = toml::from_str(&text)
            .map_err(|e| ExecutorError::Parse { path: path.into(), message: e.message().to_string() })?;
        if !(config.poll_s.is_finite() && config.poll_s > 0.0) {
            return Err(ExecutorError::Parse {
                path: path.into(),
                message: format!("poll_s must be a positive number of seconds, got {}", config.poll_s),
            });
        }
        if !(config.result_grace_s.is_finite() && config.result_grace_s >= 0.0) {
            return Err(ExecutorError::Parse {
                path: path.into(),
                message: format!("result_grace_s must be >= 0 s, got {}", config.result_grace_s),
            });
        }
        Ok(config)
    }
}

/// Where the study's jobs run.
#[derive(Clone, Debug)]
pub enum Executor {
    /// Here, `StudySpec::threads` at a time.
    Local,
    /// As Slurm job arrays.
    Slurm(SlurmConfig),
}

/// Where the study's jobs stand, for a progress bar.
#[derive(Clone, Debug, Default)]
pub struct Progress {
    /// The stage: `collect`, `label` or `train`.
    pub stage: String,
    /// Jobs of the study.
    pub jobs: usize,
    /// Jobs with a valid result.
    pub done: usize,
    /// Tasks running.
    pub running: usize,
    /// Tasks queued, not yet running.
    pub pending: usize,
    /// Tasks that failed or were cancelled and were submitted again.
    pub retried: usize,
    /// The Slurm array jobs waited for (empty when local).
    pub slurm_jobs: Vec<String>,
}

/// How one job ran, for `study --json`.
#[derive(Clone, Debug, Serialize)]
pub struct JobReport {
    /// Its index in the plan (the array task id under Slurm).
    pub index: usize,
    /// Its name (the model's, or the session's file stem).
    pub name: String,
    /// Whether its result was already there before this run (resumed).
    pub reused: bool,
    /// Times it was started by this run (0 when reused).
    pub attempts: u32,
    /// The Slurm task ids (`ARRAYJOB_TASK`) of its attempts, in order.
    pub slurm_tasks: Vec<String>,
    /// The Slurm task that ran it (its own, or another that took it), from
    /// its result; `None` when it ran here.
    pub ran_in: Option<String>,
    /// Host that ran it.
    pub host: String,
    /// When it started and finished (s since the Unix epoch).
    pub started_unix_s: f64,
    /// When it finished (s since the Unix epoch).
    pub finished_unix_s: f64,
}
