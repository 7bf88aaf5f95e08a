//! `slidetrack study`: the experiments of thesis Sec. 6.3 on the simulated
//! rig (see `slidetrack_experiment::study`), with the tables written to
//! `tables.md` and `tables.json`.

use std::collections::BTreeMap;
use std::path::Path;

use anyhow::{Result, bail};
use serde_json::{Value, json};
use slidetrack_experiment::dataset::TruthSource;
use slidetrack_experiment::dekf_run::write_atomically;
use slidetrack_experiment::dekf_train::{TrainSpec, parse_schedule};
use slidetrack_experiment::pipeline::{parallel, threads};
use slidetrack_experiment::protocol::Protocol;
use slidetrack_experiment::study::{OBJECTS, StudySpec, Tables, data, models, train_and_score};

use crate::cli::StudyArgs;

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

pub fn run(args: &StudyArgs, _quiet: bool) -> Result<()> {
    let (s, schedule) = spec(args)?;
    let stop = super::stop_flag(super::RELEASING);
    let sets = data(&s, &stop)?;
    let specs = models();
    eprintln!("training {} models, {} at a time", specs.len(), s.threads);
    let outcomes = parallel("train", &specs, s.threads, &stop, |spec| train_and_score(spec, &sets, &s))?;
    let mut tables = Tables::default();
    for (spec, o) in specs.iter().zip(&outcomes) {
        for (object, train, test) in &o.scores {
            tables.record(&spec.name, object, train.clone(), test.clone());
        }
    }
    let per_object: BTreeMap<&str, usize> =
        OBJECTS.iter().map(|o| (*o, sets[&(*o, false)].len() + sets[&(*o, true)].len())).collect();
    let trained = s.protocol.training(TrainSpec::default());
    let config = json!({
        "protocol": s.protocol.name(),
        "sessions": args.sessions,
        "sessions_per_object": per_object,
        "split": "first half (by file name) training, second half testing",
        "schedule": schedule,
        "position_shift_cm": trained.position_shift_cm,
        "epoch_selection": trained.select_epoch,
        "truth": s.truth.topic(),
        "seed": args.seed,
        "quick": args.quick,
    });
    write_outputs(&s.out, &tables, config, outcomes.into_iter().map(|o| o.summary).collect())
}

fn write_outputs(out: &Path, tables: &Tables, config: Value, models: Vec<Value>) -> Result<()> {
    let markdown = tables.markdown(&config);
    let json = json!({"config": config, "models": models, "tables": tables.json()});
    write_atomically(&out.join("tables.md"), markdown.as_bytes())?;
    write_atomically(&out.join("tables.json"), serde_json::to_string_pretty(&json)?.as_bytes())?;
    println!("{markdown}");
    println!(
        "tables written to {} and {}",
        out.join("tables.md").display(),
        out.join("tables.json").display()
    );
    Ok(())
}
