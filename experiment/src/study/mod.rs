//! The experiments of thesis Sec. 6.3 on the simulated rig: per object, its
//! sessions split 50/50 into training and testing sets; 13 dEKF models (per
//! object: xyz, xy, z with the derivative and xy with the plain signal; xy on
//! all objects) trained in parallel; Tables 6.1-6.4 with the thesis's rows
//! and columns ([`Tables`]).

pub mod executor;
mod tables;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use serde_json::{Value, json};
use slidetrack_estimators::dekf::{DekfModel, Measurement, Stage};
use slidetrack_session::{ReadOptions, SESSION_METADATA, SessionInfo};

pub use tables::{OBJECTS, Tables};

use crate::dataset::{ChannelSet, SessionData, TruthSource};
use crate::dekf_eval::score_outputs_beside;
use crate::dekf_run::run;
use crate::dekf_run::{Scores, mean_scores, save_model};
use crate::dekf_train::{TrainSpec, fit_sessions};
use crate::linear_baseline::{LinearBaseline, path_for};
use crate::protocol::Protocol;

/// The training (`false`) and testing (`true`) sessions of each object.
pub type Sets = BTreeMap<(&'static str, bool), Vec<SessionData>>;

/// One model of the study.
pub struct ModelSpec {
    /// Its name (`box-xy`, `all-xy`).
    pub name: String,
    /// Tactile channels it reads.
    pub channels: ChannelSet,
    /// What its feature network reads.
    pub measurement: Measurement,
    /// Objects whose training sets it learns from.
    pub trained_on: Vec<&'static str>,
}

/// The 13 models of the study (Tables 6.1-6.4).
pub fn models() -> Vec<ModelSpec> {
    let mut out = Vec::new();
    for object in OBJECTS {
        for (channels, measurement, suffix) in [
            (ChannelSet::Xyz, Measurement::Derivative, "xyz"),
            (ChannelSet::Xy, Measurement::Derivative, "xy"),
            (ChannelSet::Z, Measurement::Derivative, "z"),
            (ChannelSet::Xy, Measurement::Raw, "xy-raw"),
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
        measurement: Measurement::Derivative,
        trained_on: OBJECTS.to_vec(),
    });
    out
}

/// A study: where its sessions are, how many to collect, how to train.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct StudySpec {
    /// Directory of sessions, grouped by the object in their metadata.
    pub sessions: PathBuf,
    /// Directory for the models.
    pub out: PathBuf,
    /// Sessions to collect per object when the directory has none of it.
    pub collect: u32,
    /// Duration of the sliding cycles of collected sessions (s).
    pub duration_s: f64,
    /// The training schedule.
    pub schedule: Vec<Stage>,
    /// How to train (and, unless `truth` says otherwise, label).
    pub protocol: Protocol,
    /// Truth to train and score against (the protocol's, or the simulator's).
    pub truth: TruthSource,
    /// Seed of the simulated rig and of the trainings.
    pub seed: u64,
    /// Trainings (and collections) run at the same time.
    pub threads: usize,
}

/// The object of a session, from its metadata.
pub(crate) fn object_of(path: &Path) -> Result<String> {
    let info = SessionInfo::read(path, ReadOptions::default())?;
    info.metadata
        .get(SESSION_METADATA)
        .and_then(|m| m.get("object"))
        .cloned()
        .with_context(|| format!("{}: no object in the session metadata", path.display()))
}

/// Whether a session has `topic`.
pub(crate) fn has_topic(path: &Path, topic: &str) -> Result<bool> {
    Ok(SessionInfo::read(path, ReadOptions::default())?.channels.iter().any(|c| c.topic == topic))
}

/// Mean scores of `model` on `sessions`, beside the linear-map baseline
/// fitted on the model's training sessions.
fn mean_of(model: &DekfModel, linear: &LinearBaseline, sessions: &[SessionData]) -> Result<Scores> {
    let all = sessions
        .iter()
        .map(|d| score_outputs_beside(&run(model, d)?, d, Some(linear)))
        .collect::<Result<Vec<_>>>()?;
    Ok(mean_scores(&all))
}

/// The objects whose testing sets `spec` is tabled on, each with whether
/// its training set is tabled too (Table 6.1: an object's own xyz model).
pub fn scored_on(spec: &ModelSpec) -> Vec<(&'static str, bool)> {
    let xy_derivative = spec.channels == ChannelSet::Xy && spec.measurement == Measurement::Derivative;
    OBJECTS
        .iter()
        .filter_map(|&object| {
            let own = spec.trained_on == [object];
            (own || xy_derivative).then_some((object, own && spec.channels == ChannelSet::Xyz))
        })
        .collect()
}

/// The sets `spec` reads: its training sets and the sets it is scored on.
pub fn sets_of(spec: &ModelSpec) -> Vec<(&'static str, bool)> {
    let mut keys: Vec<(&'static str, bool)> = spec.trained_on.iter().map(|o| (*o, false)).collect();
    for (object, on_training_set) in scored_on(spec) {
        keys.push((object, true));
        if on_training_set {
            keys.push((object, false));
        }
    }
    keys.sort_unstable();
    keys.dedup();
    keys
}

/// A trained model of the study and its scores.
pub struct Outcome {
    /// What was trained, for `tables.json`.
    pub summary: Value,
    /// `(tested object, training-set scores, testing-set scores)`.
    pub scores: Vec<(&'static str, Option<Scores>, Scores)>,
}

/// Trains `spec` on its training sets (one thread), saves it under
/// `s.out/models`, and scores it on the testing sets it is tabled for.
pub fn train_and_score(spec: &ModelSpec, sets: &Sets, s: &StudySpec) -> Result<Outcome> {
    let train: Vec<SessionData> =
        spec.trained_on.iter().flat_map(|o| sets[&(*o, false)].iter().cloned()).collect();
    let path = s.out.join("models").join(format!("{}.safetensors", spec.name));
    let train_spec = s.protocol.training(TrainSpec {
        channels: spec.channels.names(),
        measurement: spec.measurement,
        schedule: s.schedule.clone(),
        seed: s.seed,
        threads: 1,
        truth: s.truth,
        ..TrainSpec::default()
    });
    let trained = fit_sessions(&train_spec, &train, &mut |_| {})?;
    save_model(&trained.model, &path)?;
    let linear = LinearBaseline::fit(&trained.model, &train)?;
    linear.save(&path_for(&path))?;
    let last = trained.epochs.last().map_or([f64::NAN; 2], |e| e.rmse);
    let model = &trained.model;
    let mut scores = Vec::new();
    for (object, on_training_set) in scored_on(spec) {
        let test = mean_of(model, &linear, &sets[&(object, true)])?;
        let train =
            if on_training_set { Some(mean_of(model, &linear, &sets[&(object, false)])?) } else { None };
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
