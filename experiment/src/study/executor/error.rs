//! Errors of the study's executors.

use std::path::PathBuf;

/// What went wrong planning, running or waiting for the study's jobs.
#[derive(Debug, thiserror::Error)]
pub enum ExecutorError {
    /// A file of the work directory could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file or directory.
        path: PathBuf,
        /// The error.
        source: std::io::Error,
    },
    /// A job file, result file or Slurm settings file does not parse.
    #[error("{path}: {message}")]
    Parse {
        /// The file.
        path: PathBuf,
        /// What is wrong with it.
        message: String,
    },
    /// The work directory has no job of this index.
    #[error("{work_dir}: no job {index} (the plan has {jobs} jobs)")]
    NoSuchJob {
        /// The work directory.
        work_dir: PathBuf,
        /// The index asked for.
        index: usize,
        /// Jobs in the plan.
        jobs: usize,
    },
    /// A Slurm command could not be started or failed.
    #[error("`{command}` failed: {message}")]
    Slurm {
        /// The command line.
        command: String,
        /// Its exit status and stderr, or why it could not start.
        message: String,
    },
    /// A setting or path the Slurm executor cannot pass to `sbatch`.
    #[error("{name} `{value}`: {why}")]
    Setting {
        /// What it is (`partition`, `work directory`).
        name: String,
        /// Its value.
        value: String,
        /// Why it cannot be used.
        why: &'static str,
    },
    /// Jobs still failed after every retry.
    #[error(
        "{} job(s) failed after {attempts} attempt(s) each: {}; their logs are in {}",
        failed.len(),
        failed.join(", "),
        logs.display()
    )]
    Failed {
        /// The jobs' names and their last state.
        failed: Vec<String>,
        /// Attempts each.
        attempts: u32,
        /// Directory of the tasks' logs.
        logs: PathBuf,
    },
    /// The user interrupted the study (Ctrl-C).
    #[error("interrupted{left}; run the same command again to resume")]
    Interrupted {
        /// What was left running: empty, or ` (N task(s) still queued or
        /// running in Slurm job(s) IDS)`.
        left: String,
    },
    /// A job itself failed (loading its sessions, training, scoring).
    #[error("job {name}: {message}")]
    Job {
        /// The job's name.
        name: String,
        /// What failed.
        message: String,
    },
}

/// Wraps an I/O error with its path.
pub fn io(path: impl Into<PathBuf>) -> impl FnOnce(std::io::Error) -> ExecutorError {
    let path = path.into();
    move |source| ExecutorError::Io { path, source }
}
