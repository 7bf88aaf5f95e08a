//! `slidetrack study`: the experiments of thesis Sec. 6.3 on the simulated
//! rig. Per object, a training and a testing set; 13 dEKF models (per object:
//! xyz, xy, z with the derivative and xy with the plain signal; xy on all
//! objects); Tables 6.1-6.4 with the same rows and columns as the thesis,
//! written to `tables.md` and `tables.json`.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::Ordering;

use anyhow::{Result, bail};
use clap::Args;
use serde_json::{Value, json};
use slidetrack_estimators::dekf::DekfModel;

use super::eval::score_session;
use super::study_tables::{OBJECTS, Tables};
use super::train::{MeasurementArg, TrainArgs, fit_sessions};
use crate::dataset::{ChannelSet, SessionData, TruthSource, load};
use crate::dekf_run::{Scores, mean_scores, save_model};
use crate::pipeline::{DataSpec, collect, label, threads};

/// Arguments of `study`.
#[derive(Debug, Args, Clone)]
pub struct StudyArgs {
    /// Directory for the data, the models and the tables (reused: existing
    /// sessions are kept, so an interrupted study resumes).
    #[arg(long, default_value = "study")]
    pub out: PathBuf,
    /// A small, fast version: 3 + 3 sessions of 20 s per object without
    /// camera, trained against the simulator's truth with 2 epochs per length.
    #[arg(long)]
    pub quick: bool,
    /// Sessions per object in each of the training and testing sets
    /// (default 25; the thesis had 50).
    #[arg(long)]
    pub sessions: Option<u32>,
    /// Duration of the sliding cycles of each session (s; default 60).
    #[arg(long)]
    pub duration: Option<f64>,
    /// Training schedule (default the thesis's 2:5,4:5,8:5,16:5,32:5).
    #[arg(long)]
    pub schedule: Option<String>,
    /// Truth to train and score against (default: the ArUco ground truth;
    /// `--quick`: the simulator's truth, as it records no camera).
    #[arg(long, value_enum)]
    pub truth: Option<TruthSource>,
    /// Seed of the simulated rig and of the trainings.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Worker threads (0: every core).
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
    sessions: u32,
    duration_s: f64,
    schedule: String,
    truth: TruthSource,
    camera: bool,
    threads: usize,
}

fn settings(args: &StudyArgs) -> Result<Settings> {
    let s = Settings {
        sessions: args.sessions.unwrap_or(if args.quick { 3 } else { 25 }),
        duration_s: args.duration.unwrap_or(if args.quick { 20.0 } else { 60.0 }),
        schedule: args.schedule.clone().unwrap_or_else(|| {
            if args.quick { "2:2,4:2,8:2,16:2,32:2" } else { "2:5,4:5,8:5,16:5,32:5" }.to_string()
        }),
        truth: args.truth.unwrap_or(if args.quick { TruthSource::Sim } else { TruthSource::GroundTruth }),
        camera: false,
        threads: threads(args.threads),
    };
    if s.sessions == 0 {
        bail!("--sessions must be at least 1");
    }
    if !(s.duration_s.is_finite() && s.duration_s > 0.0) {
        bail!("--duration must be a positive number of seconds, got {}", s.duration_s);
    }
    super::train::parse_schedule(&s.schedule)?;
    // The ground truth comes from the marker: it needs the camera.
    Ok(Settings { camera: s.truth == TruthSource::GroundTruth, ..s })
}

/// The training and testing sets of every object, collected (and labelled) as needed.
fn data(args: &StudyArgs, s: &Settings) -> Result<BTreeMap<(&'static str, bool), Vec<SessionData>>> {
    let stop = super::stop_flag();
    let mut sets = BTreeMap::new();
    for object in OBJECTS {
        for (test, trials) in [(false, 0..s.sessions), (true, s.sessions..2 * s.sessions)] {
            let split = if test { "test" } else { "train" };
            let dir = args.out.join("data").join(object).join(split);
            let spec = DataSpec {
                object: object.into(),
                seed: args.seed,
                trials,
                duration_s: s.duration_s,
                camera: s.camera,
            };
            eprintln!("{object} {split}: {} sessions in {}", spec.trials.len(), dir.display());
            let files = collect(&spec, &dir, s.threads, &stop, &|path, report| {
                if let Some(r) = report {
                    eprintln!("  {}", r.summary_line().replace(&path.display().to_string(), "collected"));
                }
            })?;
            if s.truth == TruthSource::GroundTruth {
                label(&files, s.threads, &stop)?;
            }
            let loaded = files.iter().map(|f| load(f, Some(s.truth))).collect::<Result<Vec<_>>>()?;
            sets.insert((object, test), loaded);
        }
    }
    if stop.load(Ordering::SeqCst) {
        bail!("interrupted; run the same command again to resume");
    }
    Ok(sets)
}

/// Mean scores of `model` on `sessions`.
fn scores(model: &DekfModel, sessions: &[SessionData]) -> Result<Scores> {
    let all = sessions.iter().map(|d| score_session(model, d)).collect::<Result<Vec<_>>>()?;
    Ok(mean_scores(&all))
}

pub fn run(args: &StudyArgs, quiet: bool) -> Result<()> {
    let s = settings(args)?;
    let sets = data(args, &s)?;
    let models_dir = args.out.join("models");
    let mut tables = Tables::default();
    let mut trained_models = Vec::new();
    for spec in models() {
        let train: Vec<SessionData> =
            spec.trained_on.iter().flat_map(|o| sets[&(*o, false)].iter().cloned()).collect();
        let path = models_dir.join(format!("{}.safetensors", spec.name));
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
            threads: s.threads,
            position_shift: super::train::DEFAULT_POSITION_SHIFT_CM,
            truth: s.truth,
            plot: None,
            json: false,
        };
        let trained = fit_sessions(&train_args, &train, quiet)?;
        save_model(&trained.model, &path)?;
        let last = trained.epochs.last().map_or([f64::NAN; 2], |e| e.rmse);
        eprintln!(
            "model {:<14} {:>3} sessions, {:.1} s; training RMSE {:.3} cm, {:.3} cm/s",
            spec.name,
            train.len(),
            trained.seconds,
            last[0],
            last[1]
        );
        let model = &trained.model;
        for object in OBJECTS {
            let own = spec.trained_on == [object];
            let relevant =
                own || spec.channels == ChannelSet::Xy && spec.measurement == MeasurementArg::Derivative;
            if !relevant {
                continue;
            }
            let test = scores(model, &sets[&(object, true)])?;
            let train_scores = if own && spec.channels == ChannelSet::Xyz {
                Some(scores(model, &sets[&(object, false)])?)
            } else {
                None
            };
            tables.record(&spec.name, object, train_scores, test);
        }
        trained_models.push(json!({
            "name": spec.name,
            "file": path,
            "trained_on": spec.trained_on,
            "channels": spec.channels.name(),
            "measurement": trained.model.meta.measurement.name(),
            "seconds": trained.seconds,
            "final_training_rmse": {"position_cm": last[0], "velocity_cmps": last[1]},
        }));
    }
    let config = json!({
        "sessions_per_split": s.sessions,
        "duration_s": s.duration_s,
        "schedule": s.schedule,
        "truth": s.truth.topic(),
        "camera": s.camera,
        "seed": args.seed,
        "quick": args.quick,
    });
    write_outputs(&args.out, &tables, config, trained_models)
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
