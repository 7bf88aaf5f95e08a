//! `slidetrack study`: the experiments of thesis Sec. 6.3 on the simulated
//! rig (see `slidetrack_experiment::study`), with the tables written to
//! `tables.md` and `tables.json`.

use std::path::Path;
use std::time::Instant;

use anyhow::{Result, bail};
use indicatif::{ProgressBar, ProgressStyle};
use serde_json::{Value, json};
use slidetrack_experiment::dataset::TruthSource;
use slidetrack_experiment::dekf_run::write_atomically;
use slidetrack_experiment::dekf_train::{TrainSpec, parse_schedule};
use slidetrack_experiment::pipeline::threads;
use slidetrack_experiment::protocol::Protocol;
use slidetrack_experiment::study::executor::{self, Executor, Progress, SlurmConfig, run_study};
use slidetrack_experiment::study::{StudySpec, Tables};

use crate::cli::{ExecutorArg, StudyArgs, StudyJobArgs};

/// The study `args` ask for, with the defaults of `--quick` or of the full study.
fn spec(args: &StudyArgs) -> Result<(StudySpec, String)> {
    let schedule = args.schedule.clone().unwrap_or_else(|| {
        if args.quick { "2:2,4:2,8:2,16:2,32:2" } else { "2:5,4:5,8:5,16:5,32:5" }.to_string()
    });
    let protocol: Protocol = args.protocol.into();
    let out = args.out.clone().unwrap_or_else(|| match protocol {
        Protocol::Default => "study".into(),
        Protocol::Thesis => "study-thesis".into(),
    });
    let spec = StudySpec {
        sessions: args.sessions.clone(),
        out,
        protocol,
        collect: args.collect.unwrap_or(if args.quick { 6 } else { 50 }),
        duration_s: args.duration.unwrap_or(if args.quick { 20.0 } else { 60.0 }),
        schedule: parse_schedule(&schedule)?,
        truth: args.truth.map_or(if args.quick { TruthSource::Sim } else { protocol.truth() }, Into::into),
        seed: args.seed,
        threads: threads(args.threads),
    };
    if spec.collect < 2 {
        bail!("--collect must be at least 2 (one training and one testing session)");
    }
    if !(spec.duration_s.is_finite() && spec.duration_s > 0.0) {
        bail!("--duration must be a positive number of seconds, got {}", spec.duration_s);
    }
    Ok((spec, schedule))
}

pub fn run(args: &StudyArgs, quiet: bool) -> Result<()> {
    let (s, schedule) = spec(args)?;
    let executor = match args.executor {
        ExecutorArg::Local => Executor::Local,
        ExecutorArg::Slurm => Executor::Slurm(
            args.slurm.as_deref().map_or_else(|| Ok(SlurmConfig::default()), SlurmConfig::read)?,
        ),
    };
    let work_dir = args.work_dir.clone().unwrap_or_else(|| s.out.join("work"));
    let stop = super::stop_flag(super::RELEASING);
    let started = Instant::now();
    let bar = progress_bar(quiet || args.json);
    let study = run_study(&s, &executor, &work_dir, &stop, &|p: &Progress| show(&bar, p))?;
    bar.finish_and_clear();
    let trained = s.protocol.training(TrainSpec::default());
    let config = json!({
        "protocol": s.protocol.name(),
        "sessions": args.sessions,
        "sessions_per_object": study.sessions_per_object,
        "split": "first half (by file name) training, second half testing",
        "schedule": schedule,
        "position_shift_cm": trained.position_shift_cm,
        "epoch_selection": trained.select_epoch,
        "truth": s.truth.topic(),
        "seed": args.seed,
        "quick": args.quick,
    });
    write_outputs(&s.out, &study.tables, config, study.models, !args.json)?;
    if args.json {
        let report = json!({
            "executor": format!("{:?}", args.executor).to_lowercase(),
            "work_dir": work_dir,
            "wall_s": started.elapsed().as_secs_f64(),
            "tables": [s.out.join("tables.md"), s.out.join("tables.json")],
            "jobs": study.jobs,
            "collect_jobs": study.collect_jobs,
            "label_jobs": study.label_jobs,
        });
        println!("{}", serde_json::to_string_pretty(&report)?);
    }
    Ok(())
}

/// `slidetrack study-job WORK INDEX`: one job of a study's work directory.
pub fn run_job(args: &StudyJobArgs) -> Result<()> {
    let report = executor::run_task(&args.work_dir, args.index, args.steal)?;
    for result in &report.ran {
        eprintln!(
            "job {} done on {} in {:.1} s",
            result.name,
            result.host,
            result.finished_unix_s - result.started_unix_s
        );
    }
    for (name, error) in &report.failed {
        eprintln!("job {name} (taken from its own task, which runs it again) failed: {error}");
    }
    Ok(())
}

/// The bar of finished jobs (hidden when `hidden`).
fn progress_bar(hidden: bool) -> ProgressBar {
    let bar = if hidden { ProgressBar::hidden() } else { ProgressBar::new(1) };
    bar.set_style(
        ProgressStyle::with_template("jobs [{bar:30}] {pos}/{len}, {elapsed} elapsed  {msg}")
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
    );
    bar
}

/// Shows `p` on `bar`.
fn show(bar: &ProgressBar, p: &Progress) {
    bar.set_length(p.jobs as u64);
    bar.set_position(p.done as u64);
    if p.slurm_jobs.is_empty() {
        bar.set_message(format!("{}: {} running", p.stage, p.running));
    } else {
        bar.set_message(format!(
            "{}: slurm job {}: {} running, {} pending, {} retried",
            p.stage,
            p.slurm_jobs.join(","),
            p.running,
            p.pending,
            p.retried
        ));
    }
}

fn write_outputs(out: &Path, tables: &Tables, config: Value, models: Vec<Value>, print: bool) -> Result<()> {
    let markdown = tables.markdown(&config);
    let json = json!({"config": config, "models": models, "tables": tables.json()});
    write_atomically(&out.join("tables.md"), markdown.as_bytes())?;
    write_atomically(&out.join("tables.json"), serde_json::to_string_pretty(&json)?.as_bytes())?;
    if print {
        println!("{markdown}");
        println!(
            "tables written to {} and {}",
            out.join("tables.md").display(),
            out.join("tables.json").display()
        );
    }
    Ok(())
}
