//! The Slurm executor: the jobs without a result as a job array (one task
//! per job, `--cpus-per-task` from the job's threads), each task running
//! `slidetrack study-job WORK INDEX`; waits for them through `squeue` and
//! the tasks' result files, and submits a failed or cancelled task again up
//! to [`SlurmConfig::retries`] times. The array jobs it submitted are kept
//! in `WORK/slurm/submitted.json`: a study run again waits for their tasks
//! that are still queued or running instead of submitting them twice.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant, SystemTime};

use serde::{Deserialize, Serialize};

use super::error::{ExecutorError, io};
use super::plan::Plan;
use super::slurm_cli::{TaskId, final_state, is_active, sacct, sbatch, scancel_pending, squeue};
use super::types::{JobReport, Progress, SlurmConfig};
use crate::dekf_run::write_atomically;

/// One array job submitted for the study.
#[derive(Clone, Debug, Serialize, Deserialize)]
struct Submission {
    /// Its id.
    job_id: u64,
    /// The jobs (array indices) it runs.
    indices: Vec<usize>,
    /// Its script.
    script: PathBuf,
}

/// The contents of `WORK/slurm/submitted.json`.
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
struct Submitted {
    arrays: Vec<Submission>,
}

/// One look at the queue.
struct Look {
    /// Jobs whose result appeared.
    done: Vec<usize>,
    /// Jobs whose task left the queue without a result, with its last state.
    lost: Vec<(usize, String)>,
    /// Tasks running.
    running: usize,
    /// Tasks pending.
    pending: usize,
}

/// A task being waited for.
struct Tracked {
    job_id: u64,
    /// When it was first seen out of the queue without a result.
    gone_since: Option<Instant>,
    /// When its job's result file was last changed, as last validated
    /// (a result file that did not validate is read again once it changes).
    result_checked: Option<SystemTime>,
}

/// How often the executor looks for new result files between two looks at
/// the queue: a file's metadata, cheap where `squeue` asks the controller.
const RESULT_LOOK: Duration = Duration::from_millis(100);

/// Quotes `s` for the shell.
fn sh_quote(s: &str) -> String {
    format!("'{}'", s.replace('\'', r"'\''"))
}

/// A setting that `#SBATCH` lines cannot carry: sbatch(1) documents no
/// quoting for them, so a value with white space is refused.
fn sbatch_line(name: &str, value: &str) -> Result<String, ExecutorError> {
    if value.chars().any(char::is_whitespace) {
        return Err(ExecutorError::Setting {
            name: name.into(),
            value: value.into(),
            why: "has white space, which an #SBATCH line cannot carry (sbatch(1) documents no quoting)",
        });
    }
    Ok(format!("#SBATCH {value}\n"))
}

/// The array script: `#SBATCH` lines of `config`'s settings, then the task
/// (paths shell-quoted). The paths Slurm needs (`--chdir`, `--output`) go
/// on `sbatch`'s command line instead ([`path_options`]).
pub fn script(
    config: &SlurmConfig,
    threads: usize,
    binary: &Path,
    work_dir: &Path,
) -> Result<String, ExecutorError> {
    let mut s = String::from("#!/bin/sh\n");
    s += &sbatch_line("job name", "--job-name=slidetrack-study")?;
    s += &sbatch_line("threads", &format!("--cpus-per-task={threads}"))?;
    for (name, value) in [
        ("partition", &config.partition),
        ("account", &config.account),
        ("time", &config.time),
        ("mem", &config.mem),
    ] {
        if let Some(v) = value {
            s += &sbatch_line(name, &format!("--{name}={v}"))?;
        }
    }
    for o in &config.sbatch_options {
        s += &sbatch_line("sbatch_options entry", o)?;
    }
    s += &format!(
        "exec {} -q study-job{} {} \"$SLURM_ARRAY_TASK_ID\"\n",
        sh_quote(&binary.display().to_string()),
        if config.steal { " --steal" } else { "" },
        sh_quote(&work_dir.display().to_string())
    );
    Ok(s)
}

/// `--chdir=CWD` and `--output=WORK/slurm/logs/%A_%a.out`, each one
/// argument of `sbatch` (so spaces need no quoting); `%` in the path is
/// written `%%` (sbatch(1), "filename pattern"). A backslash would turn
/// off the `%A`/`%a` replacement of the whole pattern, so such a work
/// directory is refused.
pub fn path_options(work_dir: &Path, cwd: &Path) -> Result<Vec<String>, ExecutorError> {
    let logs = work_dir.join("slurm/logs").display().to_string();
    if logs.contains('\\') {
        return Err(ExecutorError::Setting {
            name: "work directory".into(),
            value: work_dir.display().to_string(),
            why: "has a backslash, which turns off the %A_%a of sbatch's --output pattern",
        });
    }
    Ok(vec![format!("--chdir={}", cwd.display()), format!("--output={}/%A_%a.out", logs.replace('%', "%%"))])
}

struct Executor<'a> {
    plan: &'a Plan,
    config: &'a SlurmConfig,
    dir: PathBuf,
    submitted: Submitted,
    tracked: BTreeMap<usize, Tracked>,
    attempts: BTreeMap<usize, u32>,
    binary: PathBuf,
    cwd: PathBuf,
    work_dir: PathBuf,
    /// Whether `sacct` answers (the cluster keeps accounting); `None`
    /// until it was first asked.
    accounting: Option<bool>,
}

impl Executor<'_> {
    fn state_path(&self) -> PathBuf {
        self.dir.join("submitted.json")
    }

    /// Submits `indices`, one array per thread count.
    fn submit(&mut self, indices: &[usize]) -> Result<(), ExecutorError> {
        let mut by_threads: BTreeMap<usize, Vec<usize>> = BTreeMap::new();
        for &i in indices {
            by_threads.entry(self.plan.jobs[i].threads.max(1)).or_default().push(i);
        }
        for (threads, indices) in by_threads {
            let path = self.dir.join(format!("array-{}.sh", self.submitted.arrays.len()));
            let text = script(self.config, threads, &self.binary, &self.work_dir)?;
            std::fs::write(&path, text).map_err(io(&path))?;
            let options = path_options(&self.work_dir, &self.cwd)?;
            let job_id = sbatch(&path, &indices, self.config.max_running, &options)?;
            for &i in &indices {
                self.tracked.insert(i, Tracked { job_id, gone_since: None, result_checked: None });
                *self.attempts.entry(i).or_default() += 1;
            }
            self.submitted.arrays.push(Submission { job_id, indices, script: path });
            let text = serde_json::to_string_pretty(&self.submitted).unwrap_or_default();
            write_atomically(&self.state_path(), text.as_bytes()).map_err(|e| ExecutorError::Io {
                path: self.state_path(),
                source: std::io::Error::other(format!("{e:#}")),
            })?;
        }
        Ok(())
    }

    /// The states of the tasks of `ids`: from `sacct` where the cluster
    /// keeps accounting (tasks it has not recorded yet from `squeue`), else
    /// from `squeue` alone.
    fn states(&mut self, ids: BTreeSet<u64>) -> Result<BTreeMap<TaskId, String>, ExecutorError> {
        let ids: Vec<u64> = ids.into_iter().collect();
        if ids.is_empty() {
            return Ok(BTreeMap::new());
        }
        if self.accounting != Some(false) {
            match sacct(&ids) {
                Ok(mut states) => {
                    self.accounting = Some(true);
                    let unrecorded = self.tracked.iter().any(|(i, t)| !states.contains_key(&(t.job_id, *i)));
                    if unrecorded {
                        for (task, state) in squeue(&ids)? {
                            states.entry(task).or_insert(state);
                        }
                    }
                    return Ok(states);
                }
                // No accounting on this cluster: squeue from now on. (Once
                // sacct has answered, a failure is taken as passing, and
                // this look uses squeue.)
                Err(_) => {
                    if self.accounting.is_none() {
                        self.accounting = Some(false);
                    }
                }
            }
        }
        squeue(&ids)
    }

    /// The tasks of earlier runs still queued or running, for jobs in `pending`.
    fn adopt(&mut self, pending: &[usize]) -> Result<(), ExecutorError> {
        let mut latest: BTreeMap<usize, u64> = BTreeMap::new();
        for s in &self.submitted.arrays {
            for &i in &s.indices {
                latest.insert(i, s.job_id);
            }
        }
        let queue = self.states(latest.values().copied().collect())?;
        for (&(job_id, index), state) in &queue {
            if is_active(state) && pending.contains(&index) && latest.get(&index) == Some(&job_id) {
                self.tracked.insert(index, Tracked { job_id, gone_since: None, result_checked: None });
                self.attempts.insert(index, 1);
            }
        }
        Ok(())
    }

    /// One look at the queue: the jobs done, lost (with their last state)
    /// and the tasks running and pending.
    fn poll(&mut self) -> Result<Look, ExecutorError> {
        let queue = self.states(self.tracked.values().map(|t| t.job_id).collect())?;
        let grace = Duration::from_secs_f64(self.config.result_grace_s);
        let (mut done, mut lost, mut running, mut pending) = (Vec::new(), Vec::new(), 0, 0);
        for (&index, t) in &mut self.tracked {
            if self.plan.done(index).is_some() {
                done.push(index);
                continue;
            }
            match queue.get(&(t.job_id, index)) {
                Some(state) if is_active(state) => {
                    t.gone_since = None;
                    if state.starts_with("PENDING") { pending += 1 } else { running += 1 }
                }
                state => {
                    if t.gone_since.get_or_insert_with(Instant::now).elapsed() >= grace {
                        let state = state.cloned().unwrap_or_else(|| final_state((t.job_id, index)));
                        lost.push((index, state));
                    }
                }
            }
        }
        for i in done.iter().chain(lost.iter().map(|(i, _)| i)) {
            self.tracked.remove(i);
        }
        Ok(Look { done, lost, running, pending })
    }

    /// The tracked jobs whose result appeared (or changed) and validates,
    /// no longer tracked; from the files alone.
    fn results_in(&mut self) -> Vec<usize> {
        let mut done = Vec::new();
        for (&index, t) in &mut self.tracked {
            let Ok(modified) = std::fs::metadata(self.plan.result_path(index)).and_then(|m| m.modified())
            else {
                continue;
            };
            if t.result_checked != Some(modified) {
                t.result_checked = Some(modified);
                if self.plan.done(index).is_some() {
                    done.push(index);
                }
            }
        }
        for i in &done {
            self.tracked.remove(i);
        }
        done
    }

    /// Submits again the `lost` jobs that have attempts left; the others
    /// go to `failed`. Returns how many were submitted again.
    fn retry(
        &mut self,
        lost: Vec<(usize, String)>,
        failed: &mut Vec<String>,
    ) -> Result<usize, ExecutorError> {
        let mut again = Vec::new();
        for (index, state) in lost {
            if self.attempts.get(&index).copied().unwrap_or(0) <= self.config.retries {
                again.push(index);
            } else {
                failed.push(format!("{} ({state})", self.plan.jobs[index].name));
            }
        }
        if !again.is_empty() {
            self.submit(&again)?;
        }
        Ok(again.len())
    }

    /// Cancels the tasks of this stage's arrays still queued once every job
    /// is done: with stealing they would only start to find their jobs done.
    fn cancel_queued(&self) {
        let arrays: BTreeSet<u64> = self.submitted.arrays.iter().map(|s| s.job_id).collect();
        if let Err(e) = scancel_pending(&arrays.into_iter().collect::<Vec<_>>()) {
            tracing::debug!("study: cancelling the tasks left queued: {e}");
        }
    }

    fn job_ids(&self) -> Vec<String> {
        let ids: BTreeSet<u64> = self.tracked.values().map(|t| t.job_id).collect();
        ids.iter().map(u64::to_string).collect()
    }

    fn reports(&self, pending_at_start: &[usize]) -> Vec<JobReport> {
        (0..self.plan.jobs.len())
            .map(|index| {
                let result = self.plan.done(index);
                let tasks = self.submitted.arrays.iter().filter(|s| s.indices.contains(&index));
                JobReport {
                    index,
                    name: self.plan.jobs[index].name.clone(),
                    reused: !pending_at_start.contains(&index),
                    attempts: self.attempts.get(&index).copied().unwrap_or(0),
                    slurm_tasks: tasks.map(|s| format!("{}_{index}", s.job_id)).collect(),
                    ran_in: result.as_ref().and_then(|r| r.slurm_task.clone()),
                    host: result.as_ref().map_or_else(String::new, |r| r.host.clone()),
                    started_unix_s: result.as_ref().map_or(f64::NAN, |r| r.started_unix_s),
                    finished_unix_s: result.as_ref().map_or(f64::NAN, |r| r.finished_unix_s),
                }
            })
            .collect()
    }
}

/// Runs the jobs of `plan` without a valid result on Slurm and waits for
/// them, calling `progress` after each look at the queue; returns every
/// job's report. On `stop` it returns at once, leaving the tasks in Slurm.
pub fn run_slurm(
    plan: &Plan,
    config: &SlurmConfig,
    stop: &AtomicBool,
    progress: &(dyn Fn(&Progress) + Sync),
) -> Result<Vec<JobReport>, ExecutorError> {
    let cwd = std::env::current_dir().map_err(io("."))?;
    let dir = cwd.join(&plan.work_dir).join("slurm");
    std::fs::create_dir_all(dir.join("logs")).map_err(io(dir.join("logs")))?;
    let binary = match &config.binary {
        Some(b) => b.clone(),
        None => std::env::current_exe().map_err(io("the running slidetrack binary"))?,
    };
    let state_path = dir.join("submitted.json");
    let submitted = match std::fs::read_to_string(&state_path) {
        Ok(text) => serde_json::from_str(&text)
            .map_err(|e| ExecutorError::Parse { path: state_path.clone(), message: e.to_string() })?,
        Err(_) => Submitted::default(),
    };
    let mut ex = Executor {
        plan,
        config,
        dir,
        submitted,
        tracked: BTreeMap::new(),
        attempts: BTreeMap::new(),
        binary,
        work_dir: cwd.join(&plan.work_dir),
        cwd,
        accounting: None,
    };
    let pending_at_start = plan.pending();
    ex.adopt(&pending_at_start)?;
    let fresh: Vec<usize> =
        pending_at_start.iter().copied().filter(|i| !ex.tracked.contains_key(i)).collect();
    if !fresh.is_empty() {
        ex.submit(&fresh)?;
    }
    let (mut done, mut retried, mut failed) = (plan.jobs.len() - pending_at_start.len(), 0, Vec::new());
    let mut looked = Instant::now();
    let (mut running, mut pending) = (0, 0);
    while !ex.tracked.is_empty() {
        if stop.load(Ordering::SeqCst) {
            let left = format!(
                " ({} task(s) still queued or running in Slurm job(s) {})",
                ex.tracked.len(),
                ex.job_ids().join(",")
            );
            return Err(ExecutorError::Interrupted { left });
        }
        let poll = Duration::from_secs_f64(config.poll_s);
        std::thread::sleep(RESULT_LOOK.min(poll));
        // Results show on the (shared) file system before the queue knows;
        // the queue is asked every `poll_s`.
        let results = ex.results_in().len();
        done += results;
        if looked.elapsed() >= poll {
            looked = Instant::now();
            let Look { done: finished, lost, running: r, pending: p } = ex.poll()?;
            (running, pending) = (r, p);
            done += finished.len();
            retried += ex.retry(lost, &mut failed)?;
        } else if results == 0 {
            continue;
        }
        let slurm_jobs = ex.job_ids();
        progress(&Progress {
            jobs: plan.jobs.len(),
            done,
            running,
            pending,
            retried,
            slurm_jobs,
            ..Progress::default()
        });
    }
    if !failed.is_empty() {
        return Err(ExecutorError::Failed {
            failed,
            attempts: config.retries + 1,
            logs: ex.dir.join("logs"),
        });
    }
    if config.steal && !pending_at_start.is_empty() {
        ex.cancel_queued();
    }
    Ok(ex.reports(&pending_at_start))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_script_carries_the_settings_and_runs_one_job_per_task() {
        let config = SlurmConfig {
            partition: Some("cpu".into()),
            time: Some("00:30:00".into()),
            sbatch_options: vec!["--qos=short".into()],
            ..SlurmConfig::default()
        };
        let s = script(&config, 2, Path::new("/opt/my bin/slidetrack"), Path::new("/w/it's here"))
            .expect("script");
        assert!(s.starts_with("#!/bin/sh\n"), "{s}");
        for line in [
            "#SBATCH --cpus-per-task=2",
            "#SBATCH --partition=cpu",
            "#SBATCH --time=00:30:00",
            "#SBATCH --qos=short",
        ] {
            assert!(s.lines().any(|l| l == line), "{line} missing from\n{s}");
        }
        assert!(!s.contains("--account") && !s.contains("--mem") && !s.contains("--chdir"), "{s}");
        assert!(
            s.ends_with(
                "exec '/opt/my bin/slidetrack' -q study-job --steal '/w/it'\\''s here' \"$SLURM_ARRAY_TASK_ID\"\n"
            ),
            "{s}"
        );
    }

    #[test]
    fn paths_with_spaces_go_on_the_command_line_and_white_space_in_settings_is_refused() {
        let o = path_options(Path::new("/data/my study/100% work"), Path::new("/home/a b")).expect("options");
        assert_eq!(o, ["--chdir=/home/a b", "--output=/data/my study/100%% work/slurm/logs/%A_%a.out"]);
        let e = path_options(Path::new("/w\\x"), Path::new("/")).expect_err("backslash refused");
        assert!(e.to_string().starts_with("work directory `/w\\x`: has a backslash"), "{e}");
        let config = SlurmConfig { partition: Some("gpu large".into()), ..SlurmConfig::default() };
        let e = script(&config, 1, Path::new("/b"), Path::new("/w")).expect_err("white space refused");
        assert_eq!(e.to_string().lines().count(), 1, "{e}");
        assert!(e.to_string().starts_with("partition `--partition=gpu large`: has white space"), "{e}");
    }
}
