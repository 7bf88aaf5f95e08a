//! `study --executor slurm` against a real Slurm: the one-node cluster of
//! `scripts/slurm-test-cluster` (which `scripts/test` starts), or any
//! cluster whose `sbatch` and `squeue` are on the PATH. The tests run when
//! `SLIDETRACK_SLURM=1` and skip with a message otherwise.
//!
//! The study is the smallest that trains real models: `--quick` on two
//! 6-s sessions per object, 13 models of one short stage each.

mod common;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Stdio;
use std::sync::OnceLock;
use std::time::{Duration, Instant};

use common::{ok, slidetrack, tempdir};
use serde_json::Value;

/// Whether a Slurm cluster is there to test against; says why not otherwise.
fn slurm() -> bool {
    let on = std::env::var("SLIDETRACK_SLURM").is_ok_and(|v| v == "1");
    if !on {
        eprintln!(
            "skipped: no Slurm cluster (SLIDETRACK_SLURM is not 1); `scripts/slurm-test-cluster start` starts \
             one and `scripts/slurm-test-cluster env` prints the variables"
        );
    }
    on
}

/// The study's arguments on `sessions`, writing to `out`.
fn args(sessions: &Path, out: &Path) -> Vec<String> {
    let a = ["-q", "study", "--quick", "--collect", "2", "--duration", "6", "--schedule", "4:2,8:2"];
    let mut a: Vec<String> = a.iter().map(|s| s.to_string()).collect();
    for (k, v) in [("--sessions", sessions), ("--out", out)] {
        a.extend([k.to_string(), v.display().to_string()]);
    }
    a
}

/// A local run of the study, once per run of the tests.
struct Local {
    sessions: PathBuf,
    out: PathBuf,
}

/// The local run (in the target's test directory, replaced on each run of
/// the tests): its sessions, which the Slurm runs reuse, and its output.
///
/// Shared by the tests of one run whether they are threads of one process
/// (`cargo test`) or processes of their own (`cargo nextest`, whose
/// `NEXTEST_RUN_ID` names the run): the first to take the lock runs the
/// study and marks it done; the others wait for the lock and reuse it.
fn local() -> &'static Local {
    static LOCAL: OnceLock<Local> = OnceLock::new();
    LOCAL.get_or_init(|| {
        let root = Path::new(env!("CARGO_TARGET_TMPDIR")).join("study_slurm");
        std::fs::create_dir_all(&root).expect("the study's test directory");
        let lock = std::fs::File::create(root.join("lock")).expect("the lock file");
        lock.lock().expect("the lock");
        let run = std::env::var("NEXTEST_RUN_ID").unwrap_or_else(|_| std::process::id().to_string());
        let dir = root.join(format!("run-{run}"));
        let (sessions, out) = (dir.join("sessions"), dir.join("local"));
        if !dir.join("done").exists() {
            // Earlier runs' studies go: one run of the tests at a time.
            for old in std::fs::read_dir(&root).expect("the study's test directory") {
                let old = old.expect("an entry").path();
                if old.is_dir() {
                    std::fs::remove_dir_all(&old).expect("an earlier run's study");
                }
            }
            let a = args(&sessions, &out);
            ok(&a.iter().map(String::as_str).collect::<Vec<_>>());
            std::fs::write(dir.join("done"), "").expect("the done mark");
        }
        Local { sessions, out }
    })
}

/// Every file of `out/models`, by name.
fn models(out: &Path) -> BTreeMap<String, Vec<u8>> {
    std::fs::read_dir(out.join("models"))
        .expect("models directory")
        .map(|e| e.expect("entry").path())
        .filter(|p| p.extension().is_some_and(|e| e == "safetensors"))
        .map(|p| {
            (
                p.file_name().expect("file name").to_string_lossy().into_owned(),
                std::fs::read(&p).expect("model"),
            )
        })
        .collect()
}

/// `out`'s models and tables equal the local run's, byte for byte (the
/// tables' JSON but for the models' training times).
fn assert_same_as_local(out: &Path) {
    assert_same_outputs(&local().out, out);
}

/// `out`'s models and tables equal `expected`'s, byte for byte (the tables'
/// JSON but for the models' training times).
fn assert_same_outputs(expected: &Path, out: &Path) {
    let (a, b) = (models(expected), models(out));
    assert_eq!(a.len(), 26, "13 models and their linear baselines: {:?}", a.keys());
    assert_eq!(a.keys().collect::<Vec<_>>(), b.keys().collect::<Vec<_>>());
    for (name, bytes) in &a {
        assert!(b[name] == *bytes, "{name} differs from {}'s", expected.display());
    }
    let md = |o: &Path| std::fs::read_to_string(o.join("tables.md")).expect("tables.md");
    assert_eq!(md(expected), md(out), "tables.md");
    let tables = |o: &Path| -> Value {
        serde_json::from_str(&std::fs::read_to_string(o.join("tables.json")).expect("tables.json"))
            .expect("json")
    };
    let (t, u) = (tables(expected), tables(out));
    assert_eq!(t["tables"], u["tables"]);
    assert_eq!(t["config"], u["config"]);
}

/// Writes the executor's settings: quick polling, a short grace for results.
fn settings(dir: &Path) -> PathBuf {
    settings_with(dir, "")
}

/// [`settings`] and the lines `extra`.
fn settings_with(dir: &Path, extra: &str) -> PathBuf {
    let path = dir.join("slurm.toml");
    let text = format!("poll_s = 0.2\nresult_grace_s = 1.0\nretries = 2\ntime = \"00:10:00\"\n{extra}");
    std::fs::write(&path, text).expect("toml");
    path
}

fn slurm_args(out: &Path, toml: &Path) -> Vec<String> {
    let mut a = args(&local().sessions, out);
    a.extend(["--executor", "slurm", "--json", "--slurm"].map(String::from));
    a.push(toml.display().to_string());
    a
}

/// The models and tables of `--executor slurm` are the local run's; every
/// job ran as a task of an array job; run again, the study submits nothing
/// and reuses every result.
#[test]
fn slurm_study_equals_the_local_run_and_resumes_from_its_results() {
    if !slurm() {
        return;
    }
    let dir = tempdir();
    let out = dir.path().join("slurm");
    let a = slurm_args(&out, &settings(dir.path()));
    let a: Vec<&str> = a.iter().map(String::as_str).collect();
    let report: Value = serde_json::from_str(&ok(&a)).expect("--json report");
    assert_same_as_local(&out);
    let jobs = report["jobs"].as_array().expect("jobs");
    assert_eq!(jobs.len(), 13);
    for j in jobs {
        let tasks = j["slurm_tasks"].as_array().expect("slurm_tasks");
        assert_eq!(tasks.len(), 1, "{j}");
        assert!(tasks[0].as_str().expect("task id").ends_with(&format!("_{}", j["index"])), "{j}");
        assert!(j["finished_unix_s"].as_f64() >= j["started_unix_s"].as_f64(), "{j}");
        assert_eq!(j["reused"], false);
        // Its own task or another that took it (stealing), of the same array.
        let array = tasks[0].as_str().expect("task id").split('_').next().expect("array id");
        assert!(j["ran_in"].as_str().is_some_and(|t| t.starts_with(&format!("{array}_"))), "{j}");
    }
    let again: Value = serde_json::from_str(&ok(&a)).expect("--json report");
    for j in again["jobs"].as_array().expect("jobs") {
        assert_eq!((&j["reused"], &j["attempts"]), (&Value::Bool(true), &Value::from(0)), "{j}");
    }
    let submitted =
        std::fs::read_to_string(out.join("work/train/slurm/submitted.json")).expect("submitted.json");
    let arrays: Value = serde_json::from_str(&submitted).expect("json");
    assert_eq!(arrays["arrays"].as_array().map(Vec::len), Some(1), "{submitted}");
    assert_same_as_local(&out);
}

/// Without stealing (`steal = false`: one job per task), a task cancelled
/// while it runs (`scancel`) is submitted again and the study completes
/// with the local run's models and tables.
#[test]
fn a_task_cancelled_mid_run_is_retried_and_the_results_are_unchanged() {
    if !slurm() {
        return;
    }
    let dir = tempdir();
    let out = dir.path().join("slurm");
    let a = slurm_args(&out, &settings_with(dir.path(), "steal = false\n"));
    let study =
        slidetrack().args(&a).stdout(Stdio::piped()).stderr(Stdio::piped()).spawn().expect("study starts");
    let submitted = out.join("work/train/slurm/submitted.json");
    let started = Instant::now();
    let cancelled = loop {
        assert!(started.elapsed() < Duration::from_secs(120), "no task of the study ran within 120 s");
        std::thread::sleep(Duration::from_millis(100));
        let Ok(text) = std::fs::read_to_string(&submitted) else { continue };
        let Ok(state) = serde_json::from_str::<Value>(&text) else { continue };
        let job = state["arrays"][0]["job_id"].to_string();
        let q = std::process::Command::new("squeue")
            .args(["-h", "-r", "-t", "RUNNING", "-o", "%i", "-j", &job])
            .output()
            .expect("squeue runs");
        let running = String::from_utf8_lossy(&q.stdout).to_string();
        // The all-objects model (index 12) trains longest: cancel it when running.
        if let Some(task) = running.lines().find(|t| t.trim().ends_with("_12")) {
            let st = std::process::Command::new("scancel").arg(task.trim()).status().expect("scancel runs");
            assert!(st.success());
            break task.trim().to_string();
        }
    };
    let output = study.wait_with_output().expect("study finishes");
    assert!(output.status.success(), "study failed:\n{}", String::from_utf8_lossy(&output.stderr));
    let report: Value = serde_json::from_slice(&output.stdout).expect("--json report");
    let job = &report["jobs"][12];
    assert_eq!(job["name"], "all-xy");
    let tasks: Vec<&str> =
        job["slurm_tasks"].as_array().expect("tasks").iter().filter_map(Value::as_str).collect();
    assert_eq!(tasks.len(), 2, "cancelled {cancelled}; {job}");
    assert_eq!(tasks[0], cancelled);
    assert_eq!(job["attempts"], 2);
    assert_same_as_local(&out);
}

/// With stealing (the default), the task running the all-objects model
/// (the longest training; on a cluster of fewer than 13 cores a task that
/// took it after its own job) is cancelled while it runs: the job runs
/// again in another task and the study completes with the local run's
/// models and tables.
#[test]
fn a_task_cancelled_while_running_a_job_leaves_it_to_another_task() {
    if !slurm() {
        return;
    }
    let dir = tempdir();
    let out = dir.path().join("slurm");
    let a = slurm_args(&out, &settings(dir.path()));
    let study =
        slidetrack().args(&a).stdout(Stdio::piped()).stderr(Stdio::piped()).spawn().expect("study starts");
    let lock = out.join("work/train/locks/12-all-xy.lock");
    let started = Instant::now();
    let cancelled = loop {
        assert!(
            started.elapsed() < Duration::from_secs(120),
            "no task ran the all-objects model within 120 s"
        );
        std::thread::sleep(Duration::from_millis(20));
        if let Some(task) = holder(&lock) {
            let st = std::process::Command::new("scancel").arg(&task).status().expect("scancel runs");
            assert!(st.success());
            break task;
        }
    };
    let output = study.wait_with_output().expect("study finishes");
    assert!(output.status.success(), "study failed:\n{}", String::from_utf8_lossy(&output.stderr));
    let report: Value = serde_json::from_slice(&output.stdout).expect("--json report");
    let job = &report["jobs"][12];
    assert_eq!(job["name"], "all-xy");
    let ran_in = job["ran_in"].as_str().expect("ran_in");
    assert_ne!(ran_in, cancelled, "the cancelled task finished the job before it was cancelled: {job}");
    assert_same_as_local(&out);
}

/// The Slurm task holding the job lock `path` now (the lock file's first
/// word), if one does. (Taking the lock to look, for an instant, only
/// makes a task leave the job to another.)
fn holder(path: &Path) -> Option<String> {
    let file = std::fs::File::open(path).ok()?;
    match file.try_lock() {
        Err(std::fs::TryLockError::WouldBlock) => {
            let text = std::fs::read_to_string(path).ok()?;
            text.split_whitespace().next().filter(|t| t.contains('_')).map(String::from)
        }
        _ => None,
    }
}

/// The result files of `out`'s training jobs, by name.
fn results(out: &Path) -> BTreeMap<String, Vec<u8>> {
    let Ok(dir) = std::fs::read_dir(out.join("work/train/results")) else { return BTreeMap::new() };
    dir.filter_map(Result::ok)
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|e| e == "json"))
        .map(|p| {
            (p.file_name().expect("name").to_string_lossy().into_owned(), std::fs::read(&p).expect("result"))
        })
        .collect()
}

/// Starts the study `a`, kills the submitting process (SIGKILL) once
/// `finished` training jobs have results, runs the same command again and
/// checks: the models and tables are the local run's, and no job finished
/// before the kill ran again (its result file, with its start and end
/// times, is unchanged, and the rerun reports it reused). Returns the
/// rerun's report.
fn kill_and_resume(out: &Path, a: &[String], finished: usize) -> Value {
    let mut study =
        slidetrack().args(a).stdout(Stdio::null()).stderr(Stdio::null()).spawn().expect("study starts");
    let started = Instant::now();
    while results(out).len() < finished {
        assert!(started.elapsed() < Duration::from_secs(300), "{finished} jobs did not finish within 300 s");
        assert!(study.try_wait().expect("study polls").is_none(), "the study ended before it was killed");
        std::thread::sleep(Duration::from_millis(50));
    }
    study.kill().expect("SIGKILL");
    study.wait().expect("killed study reaped");
    let before = results(out);
    assert!(before.len() >= finished && before.len() < 13, "killed after {} of 13 jobs", before.len());
    let a: Vec<&str> = a.iter().map(String::as_str).collect();
    let report: Value = serde_json::from_str(&ok(&a)).expect("--json report");
    assert_same_as_local(out);
    let after = results(out);
    for (name, bytes) in &before {
        assert!(after.get(name) == Some(bytes), "{name}: a job finished before the kill ran again");
        let job = report["jobs"]
            .as_array()
            .expect("jobs")
            .iter()
            .find(|j| name.ends_with(&format!("-{}.json", j["name"].as_str().expect("name"))))
            .expect("job of the result");
        assert_eq!((&job["reused"], &job["attempts"]), (&Value::Bool(true), &Value::from(0)), "{job}");
    }
    report
}

/// `--executor local`, killed with SIGKILL after 3 trainings and run
/// again: the 3 are not trained again, and the models and tables are the
/// uninterrupted run's.
#[test]
fn a_local_study_killed_mid_run_resumes_without_rerunning_finished_jobs() {
    let dir = tempdir();
    let out = dir.path().join("local-killed");
    let mut a = args(&local().sessions, &out);
    a.extend(["--executor", "local", "--json", "--threads", "1"].map(String::from));
    kill_and_resume(&out, &a, 3);
}

/// `--executor slurm`, its submitting process killed with SIGKILL after 3
/// tasks finished and run again: the rerun waits for the tasks still
/// queued or running instead of submitting them again (one array job in
/// all, one task per job), runs no finished job again, and the models and
/// tables are the local run's.
#[test]
fn a_slurm_study_whose_submitter_is_killed_resumes_without_rerunning_finished_jobs() {
    if !slurm() {
        return;
    }
    let dir = tempdir();
    let out = dir.path().join("slurm-killed");
    let report = kill_and_resume(&out, &slurm_args(&out, &settings(dir.path())), 3);
    let submitted =
        std::fs::read_to_string(out.join("work/train/slurm/submitted.json")).expect("submitted.json");
    let arrays: Value = serde_json::from_str(&submitted).expect("json");
    assert_eq!(arrays["arrays"].as_array().map(Vec::len), Some(1), "{submitted}");
    for j in report["jobs"].as_array().expect("jobs") {
        assert!(j["attempts"].as_u64() <= Some(1), "{j}");
    }
}

/// A study on the labelled ground truth (collected with the camera, then
/// labelled): on Slurm, collecting and labelling run as array tasks too,
/// one per session, and the models and tables equal a local run's.
#[test]
fn collecting_and_labelling_run_as_slurm_tasks_with_the_local_runs_results() {
    if !slurm() {
        return;
    }
    let dir = tempdir();
    // Both runs collect into the same path (the linear baselines name their
    // training sessions): the local run's sessions are moved away first.
    let sessions = dir.path().join("sessions");
    let labelled = |name: &str| {
        let out = dir.path().join(name);
        let mut a = args(&sessions, &out);
        a.extend(["--truth", "ground-truth", "--json"].map(String::from));
        (out, a)
    };
    let (local_out, local_args) = labelled("local");
    ok(&local_args.iter().map(String::as_str).collect::<Vec<_>>());
    std::fs::rename(&sessions, dir.path().join("local-sessions")).expect("local sessions moved away");
    let (out, mut a) = labelled("slurm");
    a.extend(["--executor", "slurm", "--slurm"].map(String::from));
    a.push(settings(dir.path()).display().to_string());
    let report: Value =
        serde_json::from_str(&ok(&a.iter().map(String::as_str).collect::<Vec<_>>())).expect("report");
    assert_same_outputs(&local_out, &out);
    for (stage, jobs) in [("collect", 6), ("label", 6), ("train", 13)] {
        let key = if stage == "train" { "jobs".to_string() } else { format!("{stage}_jobs") };
        let list = report[&key].as_array().unwrap_or_else(|| panic!("{key} in {report}"));
        assert_eq!(list.len(), jobs, "{stage}: {report}");
        for j in list {
            assert_eq!(j["slurm_tasks"].as_array().map(Vec::len), Some(1), "{stage}: {j}");
        }
        assert!(out.join(format!("work/{stage}/slurm/submitted.json")).is_file(), "{stage}");
    }
}
