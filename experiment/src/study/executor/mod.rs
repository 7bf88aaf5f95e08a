//! The study's work as independent jobs in a shared work directory, and the
//! executors that run them: here ([`run_local`]) or as a Slurm job array
//! ([`run_slurm`]). Both write the same files, so a study's models and
//! tables do not depend on where its jobs ran.
//!
//! The work directory holds, per job (one model of [`super::models`]):
//! `jobs/NN-NAME.json` (its [`Job`]: the study's settings and the session
//! files it reads) and, once it has run, `results/NN-NAME.json` (its
//! [`JobResult`]: the model's summary and scores, and the SHA-256 of the job
//! file and of the model it wrote). A job is done when its result exists
//! and validates ([`Plan::done`]); running a study again runs only the
//! others. The Slurm executor adds `slurm/` (array scripts, task logs, the
//! submitted array jobs in `slurm/submitted.json`).

mod error;
mod job;
mod local;
mod run;
mod slurm;
mod slurm_cli;
mod types;

pub use error::ExecutorError;
pub use job::{Job, JobResult, Plan, run_job};
pub use local::run_local;
pub use run::{Executor, StudyRun, run_study};
pub use slurm::run_slurm;
pub use types::{JobReport, Progress, SlurmConfig};
