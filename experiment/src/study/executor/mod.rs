//! The study's work as independent jobs in a shared work directory, and the
//! executors that run them: here ([`run_local`]) or as Slurm job arrays
//! ([`run_slurm`]). Both write the same files, so a study's sessions,
//! models and tables do not depend on where its jobs ran.
//!
//! The work has three stages, each in its own directory of the work
//! directory ([`Plan::work_dir`]): `collect` (one job per simulated trial),
//! `label` (one job per session) and `train` (one job per model of
//! [`super::models`]). Each holds, per job, `jobs/NN-NAME.json` (its
//! [`Job`]: the study's settings and the files it reads and writes) and,
//! once it has run, `results/NN-NAME.json` (its [`JobResult`]: the SHA-256
//! of the job file and of each file it wrote, and a model's summary and
//! scores). A job is done when its result exists and validates
//! ([`Plan::done`]); running a study again runs only the others. The Slurm
//! executor adds `STAGE/slurm/` (array scripts, task logs, the submitted
//! array jobs in `slurm/submitted.json`) and `STAGE/locks/` (who runs which
//! job: see `task.rs`).

mod error;
mod job;
mod local;
mod plan;
mod run;
mod slurm;
mod slurm_cli;
mod stages;
mod stored;
mod task;
mod types;
mod work;

pub use error::ExecutorError;
pub use job::{Job, JobResult, OutputFile, Work};
pub use local::run_local;
pub use plan::Plan;
pub use run::{StudyRun, run_study};
pub use slurm::run_slurm;
pub use task::{TaskReport, run_task};
pub use types::{Executor, JobReport, Progress, SlurmConfig};
