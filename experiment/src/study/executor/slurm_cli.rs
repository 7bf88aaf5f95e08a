//! Slurm's commands as the executor uses them: `sbatch` to submit an array,
//! `sacct` for the tasks' states where the cluster keeps accounting,
//! `squeue` for the tasks still known to the controller where it does not,
//! and `scontrol show job` for the final state of a task that left the
//! queue without a result. Their outputs are parsed here (unit-tested
//! below, `sacct`'s on output captured from a real cluster).

use std::collections::BTreeMap;
use std::path::Path;
use std::process::Command;

use super::error::ExecutorError;

/// A task of an array job: `(array job id, array index)`.
pub type TaskId = (u64, usize);

/// Runs `program args`, returning its stdout, or its status and stderr.
fn run(program: &str, args: &[String]) -> Result<String, ExecutorError> {
    let command = format!("{program} {}", args.join(" "));
    let out = Command::new(program)
        .args(args)
        .output()
        .map_err(|e| ExecutorError::Slurm { command: command.clone(), message: e.to_string() })?;
    if !out.status.success() {
        let stderr = String::from_utf8_lossy(&out.stderr).trim().to_string();
        return Err(ExecutorError::Slurm { command, message: format!("{}: {stderr}", out.status) });
    }
    Ok(String::from_utf8_lossy(&out.stdout).into_owned())
}

/// `--array` of `indices`: `0,3,5` (with `%N` to run at most N at once).
pub fn array_spec(indices: &[usize], max_running: Option<u32>) -> String {
    let list: Vec<String> = indices.iter().map(usize::to_string).collect();
    match max_running {
        Some(n) if n > 0 => format!("{}%{n}", list.join(",")),
        _ => list.join(","),
    }
}

/// Submits `script` as an array of `indices`, with `options` (each one
/// argument: paths with spaces need no quoting); returns the array job's id.
pub fn sbatch(
    script: &Path,
    indices: &[usize],
    max_running: Option<u32>,
    options: &[String],
) -> Result<u64, ExecutorError> {
    let mut args = vec!["--parsable".to_string(), format!("--array={}", array_spec(indices, max_running))];
    args.extend(options.iter().cloned());
    args.push(script.display().to_string());
    let out = run("sbatch", &args)?;
    parse_sbatch(&out).ok_or_else(|| ExecutorError::Slurm {
        command: format!("sbatch {}", args.join(" ")),
        message: format!("no job id in its output `{}`", out.trim()),
    })
}

/// The job id of `sbatch --parsable`'s output (`ID` or `ID;CLUSTER`).
pub fn parse_sbatch(out: &str) -> Option<u64> {
    out.lines().rev().find(|l| !l.trim().is_empty())?.trim().split(';').next()?.parse().ok()
}

/// Cancels the tasks of `jobs` still pending (`scancel --state=PENDING`):
/// those already running or ended are left alone.
pub fn scancel_pending(jobs: &[u64]) -> Result<(), ExecutorError> {
    if jobs.is_empty() {
        return Ok(());
    }
    let mut args = vec!["--state=PENDING".to_string()];
    args.extend(jobs.iter().map(u64::to_string));
    run("scancel", &args).map(|_| ())
}

/// The tasks of `jobs` the controller still knows, with their state
/// (`PENDING`, `RUNNING`, `COMPLETING`, `CANCELLED`, ...). Jobs it has
/// forgotten are left out.
pub fn squeue(jobs: &[u64]) -> Result<BTreeMap<TaskId, String>, ExecutorError> {
    if jobs.is_empty() {
        return Ok(BTreeMap::new());
    }
    let ids: Vec<String> = jobs.iter().map(u64::to_string).collect();
    let args = ["-h", "-r", "-o", "%i|%T", "-j"]
        .iter()
        .map(|s| s.to_string())
        .chain([ids.join(",")])
        .collect::<Vec<_>>();
    match run("squeue", &args) {
        Ok(out) => Ok(parse_squeue(&out)),
        // Every id purged from the controller's memory (MinJobAge).
        Err(ExecutorError::Slurm { message, .. }) if message.contains("Invalid job id") => {
            Ok(BTreeMap::new())
        }
        Err(e) => Err(e),
    }
}

/// The states of the tasks of `jobs` from the accounting database:
/// `sacct -n -P -X -o JobID,State -j IDS` (with `-j` and no `-S`, every
/// job since the epoch, sacct(1)). `Err` where the cluster keeps no
/// accounting (`sacct` then fails: "Slurm accounting storage is disabled").
pub fn sacct(jobs: &[u64]) -> Result<BTreeMap<TaskId, String>, ExecutorError> {
    if jobs.is_empty() {
        return Ok(BTreeMap::new());
    }
    let ids: Vec<String> = jobs.iter().map(u64::to_string).collect();
    let args = ["-n", "-P", "-X", "-o", "JobID,State", "-j"]
        .iter()
        .map(|s| s.to_string())
        .chain([ids.join(",")])
        .collect::<Vec<_>>();
    Ok(parse_squeue(&run("sacct", &args)?))
}

/// Lines `ID_INDEX|STATE` of `squeue -r -o '%i|%T'` or of `sacct -P -o
/// JobID,State` (further `|` fields ignored); a not yet expanded
/// `ID_[1-3,5%2]` stands for each of its indices; job steps
/// (`ID_INDEX.batch`) and jobs that are not array tasks are left out.
pub fn parse_squeue(out: &str) -> BTreeMap<TaskId, String> {
    let mut tasks = BTreeMap::new();
    for line in out.lines() {
        let mut fields = line.trim().split('|');
        let (Some(id), Some(state)) = (fields.next(), fields.next()) else { continue };
        let Some((job, index)) = id.split_once('_') else { continue };
        if index.contains('.') {
            continue;
        }
        let Ok(job) = job.parse::<u64>() else { continue };
        for index in parse_indices(index) {
            tasks.insert((job, index), state.trim().to_string());
        }
    }
    tasks
}

/// `4`, `[4-6,9]` or `[4-6%2]` as indices.
fn parse_indices(text: &str) -> Vec<usize> {
    let text = text.trim_start_matches('[').trim_end_matches(']');
    let text = text.split('%').next().unwrap_or("");
    let mut out = Vec::new();
    for part in text.split(',') {
        match part.split_once('-') {
            Some((a, b)) => {
                if let (Ok(a), Ok(b)) = (a.parse::<usize>(), b.parse::<usize>()) {
                    out.extend(a..=b);
                }
            }
            None => out.extend(part.parse::<usize>().ok()),
        }
    }
    out
}

/// Whether a task in `state` may still run (or is still finishing).
pub fn is_active(state: &str) -> bool {
    let state = state.split_whitespace().next().unwrap_or("");
    matches!(
        state,
        "PENDING"
            | "RUNNING"
            | "CONFIGURING"
            | "COMPLETING"
            | "SUSPENDED"
            | "REQUEUED"
            | "REQUEUE_HOLD"
            | "REQUEUE_FED"
            | "RESIZING"
            | "SIGNALING"
            | "STAGE_OUT"
            | "STOPPED"
    )
}

/// The final state of a task that left the queue (without accounting):
/// from `scontrol show job` while the controller remembers it, else `unknown`.
pub fn final_state(task: TaskId) -> String {
    let id = format!("{}_{}", task.0, task.1);
    if let Ok(out) = run("scontrol", &["show".into(), "job".into(), id])
        && let Some(state) = parse_scontrol_state(&out)
    {
        return state;
    }
    "unknown".into()
}

/// `JobState=X` of `scontrol show job`'s output.
pub fn parse_scontrol_state(out: &str) -> Option<String> {
    out.split_whitespace().find_map(|w| w.strip_prefix("JobState=")).map(String::from)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sbatch_parsable_output_gives_the_job_id() {
        assert_eq!(parse_sbatch("1234\n"), Some(1234));
        assert_eq!(parse_sbatch("1234;cluster\n"), Some(1234));
        assert_eq!(parse_sbatch("sbatch: error: x\n"), None);
    }

    #[test]
    fn squeue_lines_expand_unsplit_arrays() {
        let out = "12_3|RUNNING\n12_[4-6,9%2]|PENDING\n13_0|COMPLETING\nnot a line\n14|RUNNING\n";
        let t = parse_squeue(out);
        assert_eq!(t.get(&(12, 3)).map(String::as_str), Some("RUNNING"));
        for i in [4, 5, 6, 9] {
            assert_eq!(t.get(&(12, i)).map(String::as_str), Some("PENDING"), "{i}");
        }
        assert_eq!(t.len(), 6);
        assert!(
            is_active("COMPLETING")
                && is_active("PENDING")
                && !is_active("CANCELLED")
                && !is_active("FAILED")
        );
        assert!(!is_active("CANCELLED by 0"));
    }

    /// `sacct -P -j ID -o jobid,state,exitcode,nodelist` of a two-task array
    /// on a real cluster (NERSC's Cori), as captured in
    /// <https://github.com/reframe-hpc/reframe/issues/839>: the tasks and
    /// their steps (`.batch`, `.extern`, `.0`), `|`-separated with no
    /// trailing `|` (sacct(1), `--parsable2`).
    const SACCT_CORI: &str = "JobID|State|ExitCode|NodeList
22423095_1|COMPLETED|0:0|nid0[2544-2545]
22423095_1.batch|COMPLETED|0:0|nid02544
22423095_1.extern|COMPLETED|0:0|nid0[2544-2545]
22423095_1.0|COMPLETED|0:0|nid0[2544-2545]
22423095_0|RUNNING|0:0|nid0[2517-2518]
22423095_0.extern|RUNNING|0:0|nid0[2517-2518]
";

    #[test]
    fn sacct_parsable_output_gives_each_tasks_state_and_skips_steps() {
        let t = parse_squeue(SACCT_CORI);
        assert_eq!(t.len(), 2, "{t:?}");
        assert_eq!(t.get(&(22423095, 1)).map(String::as_str), Some("COMPLETED"));
        assert_eq!(t.get(&(22423095, 0)).map(String::as_str), Some("RUNNING"));
        // A cancelled task's state followed by who cancelled it (sacct(1),
        // State: "the UID that CANCELLED a job"); a pending array not yet
        // split into tasks as its index range, as squeue prints it.
        let t = parse_squeue("7_2|CANCELLED by 1000\n7_[3-4%1]|PENDING\n7_0|FAILED\n");
        assert_eq!(t.get(&(7, 2)).map(String::as_str), Some("CANCELLED by 1000"));
        assert!(!is_active(&t[&(7, 2)]) && !is_active(&t[&(7, 0)]) && is_active(&t[&(7, 4)]));
        assert_eq!(t.len(), 4);
    }

    #[test]
    fn array_specs_and_scontrol_states() {
        assert_eq!(array_spec(&[0, 3, 5], None), "0,3,5");
        assert_eq!(array_spec(&[1], Some(4)), "1%4");
        let out = "JobId=15 ArrayJobId=12 ArrayTaskId=3 JobName=x\n   JobState=CANCELLED Reason=None";
        assert_eq!(parse_scontrol_state(out).as_deref(), Some("CANCELLED"));
    }
}
