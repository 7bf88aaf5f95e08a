//! What one Slurm task does (`slidetrack study-job [--steal] STAGE_DIR
//! INDEX`): its own job, then, stealing, the stage's other jobs that have
//! no result and that no other task is running.
//!
//! Why steal: a cluster starts an array's tasks as cores free up, and
//! between a task's end and the next task's start its scheduler may take
//! seconds (about 3 s on the one-node test cluster, for trainings of
//! 0.3 s). Tasks that take the next job themselves keep the cores busy;
//! the tasks that start later find their jobs done and end at once, and
//! the executor cancels those still queued once every result is in.
//!
//! Who runs what is settled by a lock per job, `STAGE/locks/NN-NAME.lock`
//! (`flock(2)`, through [`std::fs::File::try_lock`]; the file says which
//! task, host and process last took it): the kernel releases
//! it when its holder ends, however it ends, so a task cancelled in the
//! middle of a stolen job leaves that job to its own task. A task whose
//! own job another task holds steals the rest first, then waits for that
//! lock and runs the job itself if no result came. Jobs give the same
//! bytes wherever they run, so a file system whose locks do not reach
//! across nodes costs only a job run twice, never a different result.

use std::fs::{File, TryLockError};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;

use super::error::{ExecutorError, io};
use super::job::JobResult;
use super::plan::{Plan, host_name, slurm_task};

/// What a task ran.
#[derive(Debug, Default)]
pub struct TaskReport {
    /// The jobs it ran, its own first when it ran it.
    pub ran: Vec<JobResult>,
    /// Stolen jobs that failed, with the error (their own tasks run them
    /// again and report).
    pub failed: Vec<(String, String)>,
}

impl Plan {
    /// `STAGE/locks/NN-NAME.lock`.
    fn lock_path(&self, index: usize) -> PathBuf {
        self.work_dir.join("locks").join(format!("{index:02}-{}.lock", self.jobs[index].name))
    }

    /// Opens job `index`'s lock file (made when missing).
    fn lock_file(&self, index: usize) -> Result<File, ExecutorError> {
        let path = self.lock_path(index);
        if let Some(dir) = path.parent() {
            std::fs::create_dir_all(dir).map_err(io(dir))?;
        }
        File::options().create(true).truncate(false).write(true).open(&path).map_err(io(&path))
    }

    /// Job `index`'s lock if no one holds it; `None` when another task does.
    fn try_lock(&self, index: usize) -> Result<Option<File>, ExecutorError> {
        let file = self.lock_file(index)?;
        match file.try_lock() {
            Ok(()) => self.holding(index, file).map(Some),
            Err(TryLockError::WouldBlock) => Ok(None),
            Err(TryLockError::Error(e)) => Err(io(self.lock_path(index))(e)),
        }
    }

    /// Writes who holds job `index`'s lock `file` into it: the Slurm task,
    /// host and process (for people and tests; the lock is what counts).
    fn holding(&self, index: usize, mut file: File) -> Result<File, ExecutorError> {
        let task = slurm_task().unwrap_or_else(|| "-".into());
        let text = format!("{task} {} {}\n", host_name(), std::process::id());
        file.set_len(0).and_then(|()| file.write_all(text.as_bytes())).map_err(io(self.lock_path(index)))?;
        Ok(file)
    }

    /// Runs job `index` under its lock `lock` unless it has a valid result.
    fn run_locked(&self, index: usize, lock: File) -> Result<Option<JobResult>, ExecutorError> {
        let result = if self.done(index).is_some() {
            None
        } else {
            Some(self.execute(index, None, &AtomicBool::new(false))?)
        };
        drop(lock);
        Ok(result)
    }
}

/// Runs task `index` of the stage in `work_dir`: job `index`, then with
/// `steal` the stage's other jobs of as many threads that have no result
/// file and no holder, from the last one down (the cluster starts tasks
/// from the first up). An error of the task's own job is the task's error;
/// a stolen job's is reported and left to that job's own task.
pub fn run_task(work_dir: &Path, index: usize, steal: bool) -> Result<TaskReport, ExecutorError> {
    let plan = Plan::read(work_dir)?;
    if index >= plan.jobs.len() {
        return Err(ExecutorError::NoSuchJob { work_dir: work_dir.into(), index, jobs: plan.jobs.len() });
    }
    let mut report = TaskReport::default();
    let own_held_elsewhere = match plan.try_lock(index)? {
        Some(lock) => {
            report.ran.extend(plan.run_locked(index, lock)?);
            false
        }
        None => true,
    };
    if steal {
        let threads = plan.jobs[index].threads;
        for other in (0..plan.jobs.len()).rev() {
            // A result file, valid or not, is left alone: one that is not
            // valid was pending when the array was submitted, and the
            // job's own task checks and runs it.
            if other == index || plan.jobs[other].threads != threads || plan.result_path(other).exists() {
                continue;
            }
            let Some(lock) = plan.try_lock(other)? else { continue };
            match plan.run_locked(other, lock) {
                Ok(ran) => report.ran.extend(ran),
                Err(e) => report.failed.push((plan.jobs[other].name.clone(), e.to_string())),
            }
        }
    }
    if own_held_elsewhere {
        // Another task runs this job: wait for it, and run the job if that
        // task ended without a result (cancelled, failed).
        let lock = plan.lock_file(index)?;
        lock.lock().map_err(io(plan.lock_path(index)))?;
        let lock = plan.holding(index, lock)?;
        report.ran.extend(plan.run_locked(index, lock)?);
    }
    Ok(report)
}
