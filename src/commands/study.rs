//! `slidetrack study`: the experiments of thesis Sec. 6.3 on the simulated
//! rig. Per object, its sessions split 50/50 into training and testing sets;
//! 13 dEKF models (per object: xyz, xy, z with the derivative and xy with the
//! plain signal; xy on all objects) trained in parallel; Tables 6.1-6.4 with
//! the same rows and columns as the thesis, written to `tables.md` and
//! `tables.json`.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::Ordering;

use anyhow::{Context, Result, bail};
use clap::Args;
use serde_json::{Value, json};
use slidetrack_drivers::session::{ReadOptions, SESSION_METADATA, SessionInfo};
use slidetrack_estimators::dekf::DekfModel;

use super::eval::score_session;
use super::study_tables::{OBJECTS, Tables};
use super::train::{MeasurementArg, TrainArgs, fit_sessions};
use crate::dataset::{ChannelSet, SessionData, TruthSource, expand, load};
use crate::dekf_run::{Scores, mean_scores, save_model};
use crate::pipeline::{DataSpec, collect, label, parallel, threads};

/// Arguments of `study`.
#[derive(Debug, Args, Clone)]
pub struct StudyArgs {
    /// Directory of sessions, grouped by the object in their metadata; each
    /// object's sessions (sorted by name) are split 50/50 into training and
    /// testing sets. Objects without sessions there are collected into it
    /// first (see `--collect`), and unlabelled sessions are labelled.
    #[arg(long, default_value = "study/sessions")]
    pub sessions: PathBuf,
    /// Directory for the models and the tables.
    #[arg(long, default_value = "study")]
    pub out: PathBuf,
    /// A small, fast version: 3 + 3 sessions of 20 s per object collected
    /// without camera, trained against the simulator's truth with 2 epochs per length.
    #[arg(long)]
    pub quick: bool,
    /// Sessions to collect per object when the directory has none of it
    /// (default 50, as the thesis; 6 with `--quick`).
    #[arg(long)]
    pub collect: Option<u32>,
    /// Duration of the sliding cycles of collected sessions (s; default 60, 20 with `--quick`).
    #[arg(long)]
    pub duration: Option<f64>,
    /// Training schedule (default the thesis's 2:5,4:5,8:5,16:5,32:5).
    #[arg(long)]
    pub schedule: Option<String>,
    /// Truth to train and score against (default: the ArUco ground truth;
    /// `--quick`: the simulator's truth, as it collects no camera).
    #[arg(long, value_enum)]
    pub truth: Option<TruthSource>,
    /// Seed of the simulated rig and of the trainings.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Trainings run at the same time, one core each (0: every core).
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
}

/// One model of the study.
struct ModelSpec {
    name: String,
    channels: ChannelSet,
    measurement: MeasurementArg,
    /// Objects whose training sets it learns from.
    trained_on: Vec<&'static str>,
}

fn models() -> Vec<ModelSpec> {
    let mut out = Vec::new();
    for object in OBJECTS {
        for (channels, measurement, suffix) in [
            (ChannelSet::Xyz, MeasurementArg::Derivative, "xyz"),
            (ChannelSet::Xy, MeasurementArg::Derivative, "xy"),
            (ChannelSet::Z, MeasurementArg::Derivative, "z"),
            (ChannelSet::Xy, MeasurementArg::Raw, "xy-raw"),
        ] {
            out.push(ModelSpec {
                name: format!("{object}-{suffix}"),
                channels,
                measurement,
                trained_on: vec![object],
            });
        }
    }
    out.push(ModelSpec {
        name: "all-xy".into(),
        channels: ChannelSet::Xy,
        measurement: MeasurementArg::Derivative,
        trained_on: OBJECTS.to_vec(),
    });
    out
}

/// The resolved settings.
struct Settings {
    collect: u32,
    duration_s: f64,
    schedule: String,
    truth: TruthSource,
    threads: usize,
}

fn settings(args: &StudyArgs) -> Result<Settings> {
    let s = Settings {
        collect: args.collect.unwrap_or(if args.quick { 6 } else { 50 }),
        duration_s: args.duration.unwrap_or(if args.quick { 20.0 } else { 60.0 }),
        schedule: args.schedule.clone().unwrap_or_else(|| {
            if args.quick { "2:2,4:2,8:2,16:2,32:2" } else { "2:5,4:5,8:5,16:5,32:5" }.to_string()
        }),
        truth: args.truth.unwrap_or(if args.quick { TruthSource::Sim } else { TruthSource::GroundTruth }),
        threads: threads(args.threads),
    };
    if s.collect < 2 {
        bail!("--collect must be at least 2 (one training and one testing session)");
    }
    if !(s.duration_s.is_finite() && s.duration_s > 0.0) {
        bail!("--duration must be a positive number of seconds, got {}", s.duration_s);
    }
    super::train::parse_schedule(&s.schedule)?;
    Ok(s)
}

/// The object of a session, from its metadata.
fn object_of(path: &Path) -> Result<String> {
    let info = SessionInfo::read(path, ReadOptions::default())?;
    info.metadata
        .get(SESSION_METADATA)
        .and_then(|m| m.get("object"))
        .cloned()
        .with_context(|| format!("{}: no object in the session metadata", path.display()))
}

/// Whether a session has `topic`.
fn has_topic(path: &Path, topic: &str) -> Result<bool> {
    Ok(SessionInfo::read(path, ReadOptions::default())?.channels.iter().any(|c| c.topic == topic))
}

/// The training and testing sets of every object: the sessions of `args.sessions`
/// split 50/50, collected and labelled as needed.
fn data(args: &StudyArgs, s: &Settings) -> Result<BTreeMap<(&'static str, bool), Vec<SessionData>>> {
    let stop = super::stop_flag();
    std::fs::create_dir_all(&args.sessions)
        .with_context(|| format!("cannot create {}", args.sessions.display()))?;
    let mut by_object: BTreeMap<String, Vec<PathBuf>> = BTreeMap::new();
    if let Ok(files) = expand(std::slice::from_ref(&args.sessions)) {
        for f in files {
            by_object.entry(object_of(&f)?).or_default().push(f);
        }
    }
    let mut sets = BTreeMap::new();
    for object in OBJECTS {
        let mut files = by_object.remove(object).unwrap_or_default();
        if files.is_empty() {
            let spec = DataSpec {
                object: object.into(),
                seed: args.seed,
                trials: 0..s.collect,
                duration_s: s.duration_s,
                camera: s.truth == TruthSource::GroundTruth,
            };
            eprintln!("{object}: collecting {} sessions into {}", s.collect, args.sessions.display());
            files = collect(&spec, &args.sessions, s.threads, &stop, &|_, report| {
                if let Some(r) = report {
                    eprintln!("  {}", r.summary_line());
                }
            })?;
        }
        if files.len() < 2 {
            bail!(
                "{object}: {} session(s) in {}; the study needs at least 2",
                files.len(),
                args.sessions.display()
            );
        }
        if s.truth == TruthSource::GroundTruth {
            let unlabelled: Vec<PathBuf> = files
                .iter()
                .filter(|f| !has_topic(f, crate::dataset::GROUND_TRUTH_TOPIC).unwrap_or(false))
                .cloned()
                .collect();
            if !unlabelled.is_empty() {
                eprintln!("{object}: labelling {} sessions", unlabelled.len());
                label(&unlabelled, s.threads, &stop)?;
            }
        }
        files.sort();
        let half = files.len() / 2;
        for (test, part) in [(false, &files[..half]), (true, &files[half..])] {
            let loaded = part.iter().map(|f| load(f, Some(s.truth))).collect::<Result<Vec<_>>>()?;
            sets.insert((object, test), loaded);
        }
    }
    if stop.load(Ordering::SeqCst) {
        bail!("interrupted; run the same command again to resume");
    }
    Ok(sets)
}

/// Mean scores of `model` on `sessions`.
fn mean_of(model: &DekfModel, sessions: &[SessionData]) -> Result<Scores> {
    let all = sessions.iter().map(|d| score_session(model, d)).collect::<Result<Vec<_>>>()?;
    Ok(mean_scores(&all))
}

/// A trained model of the study and its scores.
struct Outcome {
    summary: Value,
    /// `(tested object, training-set scores, testing-set scores)`.
    scores: Vec<(&'static str, Option<Scores>, Scores)>,
}

fn train_and_score(
    spec: &ModelSpec,
    sets: &BTreeMap<(&'static str, bool), Vec<SessionData>>,
    s: &Settings,
    args: &StudyArgs,
) -> Result<Outcome> {
    let train: Vec<SessionData> =
        spec.trained_on.iter().flat_map(|o| sets[&(*o, false)].iter().cloned()).collect();
    let path = args.out.join("models").join(format!("{}.safetensors", spec.name));
    let train_args = TrainArgs {
        sessions: Vec::new(),
        channels: spec.channels,
        measurement: spec.measurement,
        out: path.clone(),
        rate_hz: 30.0,
        schedule: s.schedule.clone(),
        batch: 32,
        lr: 1e-3,
        seed: args.seed,
        threads: 1,
        position_shift: super::train::DEFAULT_POSITION_SHIFT_CM,
        no_select: false,
        truth: s.truth,
        plot: None,
        json: false,
    };
    let trained = fit_sessions(&train_args, &train, true)?;
    save_model(&trained.model, &path)?;
    let last = trained.epochs.last().map_or([f64::NAN; 2], |e| e.rmse);
    let model = &trained.model;
    let mut scores = Vec::new();
    let xy_derivative = spec.channels == ChannelSet::Xy && spec.measurement == MeasurementArg::Derivative;
    for object in OBJECTS {
        let own = spec.trained_on == [object];
        if !(own || xy_derivative) {
            continue;
        }
        let test = mean_of(model, &sets[&(object, true)])?;
        let train = if own && spec.channels == ChannelSet::Xyz {
            Some(mean_of(model, &sets[&(object, false)])?)
        } else {
            None
        };
        scores.push((object, train, test));
    }
    eprintln!(
        "model {:<14} {:>3} sessions, {:.1} s; training RMSE {:.3} cm, {:.3} cm/s",
        spec.name,
        train.len(),
        trained.seconds,
        last[0],
        last[1]
    );
    let summary = json!({
        "name": spec.name,
        "file": path,
        "trained_on": spec.trained_on,
        "channels": spec.channels.name(),
        "measurement": trained.model.meta.measurement.name(),
        "sessions": train.len(),
        "seconds": trained.seconds,
        "final_training_rmse": {"position_cm": last[0], "velocity_cmps": last[1]},
    });
    Ok(Outcome { summary, scores })
}

pub fn run(args: &StudyArgs, _quiet: bool) -> Result<()> {
    let s = settings(args)?;
    let sets = data(args, &s)?;
    let specs = models();
    eprintln!("training {} models, {} at a time", specs.len(), s.threads);
    let stop = super::stop_flag();
    let outcomes =
        parallel("train", &specs, s.threads, &stop, |spec| train_and_score(spec, &sets, &s, args))?;
    let mut tables = Tables::default();
    for (spec, o) in specs.iter().zip(&outcomes) {
        for (object, train, test) in &o.scores {
            tables.record(&spec.name, object, train.clone(), test.clone());
        }
    }
    let per_object: BTreeMap<&str, usize> =
        OBJECTS.iter().map(|o| (*o, sets[&(*o, false)].len() + sets[&(*o, true)].len())).collect();
    let config = json!({
        "sessions": args.sessions,
        "sessions_per_object": per_object,
        "split": "first half (by file name) training, second half testing",
        "schedule": s.schedule,
        "position_shift_cm": super::train::DEFAULT_POSITION_SHIFT_CM,
        "truth": s.truth.topic(),
        "seed": args.seed,
        "quick": args.quick,
    });
    write_outputs(&args.out, &tables, config, outcomes.into_iter().map(|o| o.summary).collect())
}

fn write_outputs(out: &Path, tables: &Tables, config: Value, models: Vec<Value>) -> Result<()> {
    let markdown = tables.markdown(&config);
    let json = json!({"config": config, "models": models, "tables": tables.json()});
    crate::dekf_run::write_atomically(&out.join("tables.md"), markdown.as_bytes())?;
    crate::dekf_run::write_atomically(
        &out.join("tables.json"),
        serde_json::to_string_pretty(&json)?.as_bytes(),
    )?;
    println!("{markdown}");
    println!(
        "tables written to {} and {}",
        out.join("tables.md").display(),
        out.join("tables.json").display()
    );
    Ok(())
}
