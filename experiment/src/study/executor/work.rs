//! What each kind of job does ([`perform`]) and the jobs of each stage of a
//! study: collecting ([`collect_jobs`]), labelling ([`label_jobs`]) and
//! training ([`train_jobs`]).

use std::path::PathBuf;
use std::sync::atomic::AtomicBool;

use anyhow::{Context, Result};
use serde_json::Value;

use super::job::{Job, ScoreRow, SetFiles, Work};
use crate::dataset::{SessionData, load};
use crate::linear_baseline::path_for;
use crate::pipeline::{DataSpec, collect, label};
use crate::protocol::Protocol;
use crate::study::{OBJECTS, Sets, StudySpec, has_topic, models, sets_of, train_and_score};
use crate::trial::session_file_name;

/// What a job produced.
pub struct Performed {
    /// The files it wrote, with whether a later stage rewrites them.
    pub outputs: Vec<(PathBuf, bool)>,
    /// A training job's model summary.
    pub summary: Value,
    /// A training job's scores.
    pub scores: Vec<ScoreRow>,
}

/// The study's settings as its jobs carry them: results do not depend on
/// the threads.
fn settings(study: &StudySpec) -> StudySpec {
    StudySpec { threads: 1, ..study.clone() }
}

/// One job per trial `0..study.collect` of each of `objects`.
pub fn collect_jobs(study: &StudySpec, objects: &[&str]) -> Vec<Job> {
    let settings = settings(study);
    objects
        .iter()
        .flat_map(|object| (0..study.collect).map(move |trial| (object.to_string(), trial)))
        .enumerate()
        .map(|(index, (object, trial))| {
            let file = session_file_name(&object, study.seed, trial);
            let session = study.sessions.join(&file);
            Job {
                index,
                name: file.trim_end_matches(".mcap").to_string(),
                threads: 1,
                study: settings.clone(),
                work: Work::Collect { object, trial, session },
            }
        })
        .collect()
}

/// One job per file of `sessions` (in this order), labelling with `protocol`.
pub fn label_jobs(study: &StudySpec, protocol: Protocol, sessions: &[PathBuf]) -> Vec<Job> {
    let settings = settings(study);
    sessions
        .iter()
        .enumerate()
        .map(|(index, session)| Job {
            index,
            name: session
                .file_stem()
                .map_or_else(|| format!("session{index}"), |s| s.to_string_lossy().into()),
            threads: 1,
            study: settings.clone(),
            work: Work::Label { protocol, session: session.clone() },
        })
        .collect()
}

/// One job per model of [`models`], on the files of `sets`.
pub fn train_jobs(study: &StudySpec, sets: &Sets) -> Vec<Job> {
    let settings = settings(study);
    models()
        .iter()
        .enumerate()
        .map(|(index, spec)| Job {
            index,
            name: spec.name.clone(),
            threads: 1,
            study: settings.clone(),
            work: Work::Train {
                sets: sets_of(spec)
                    .into_iter()
                    .map(|(object, testing)| SetFiles {
                        object: object.into(),
                        testing,
                        files: sets[&(object, testing)].iter().map(|d| d.path.clone()).collect(),
                    })
                    .collect(),
            },
        })
        .collect()
}

/// The object of [`OBJECTS`] named `name`.
pub fn object(name: &str) -> Result<&'static str> {
    OBJECTS.iter().copied().find(|o| *o == name).with_context(|| format!("no object `{name}` in the study"))
}

/// The training job's sets, loaded from their files.
fn load_sets(job: &Job, sets: &[SetFiles]) -> Result<Sets> {
    let mut loaded = Sets::new();
    for set in sets {
        let data =
            set.files.iter().map(|f| load(f, Some(job.study.truth))).collect::<Result<Vec<SessionData>>>()?;
        loaded.insert((object(&set.object)?, set.testing), data);
    }
    Ok(loaded)
}

/// Does `job`: training on `sets` when given (the submitting machine has
/// them loaded), else on its sessions loaded from their files.
pub fn perform(job: &Job, sets: Option<&Sets>, stop: &AtomicBool) -> Result<Performed> {
    let none = |outputs| Performed { outputs, summary: Value::Null, scores: Vec::new() };
    let study = &job.study;
    match &job.work {
        Work::Collect { object, trial, session } => {
            let spec = DataSpec {
                object: object.clone(),
                seed: study.seed,
                trials: *trial..trial + 1,
                duration_s: study.duration_s,
                camera: study.truth.is_labelled(),
            };
            let written = collect(&spec, &study.sessions, 1, stop, &|_, report| {
                if let Some(r) = report {
                    eprintln!("  {}", r.summary_line());
                }
            })?;
            anyhow::ensure!(
                written.iter().any(|w| w == session),
                "collecting trial {trial} of {object} wrote {written:?}, not {}",
                session.display()
            );
            Ok(none(vec![(session.clone(), study.truth.is_labelled())]))
        }
        Work::Label { protocol, session } => {
            if !has_topic(session, study.truth.topic())? {
                label(std::slice::from_ref(session), *protocol, 1, stop)?;
            }
            Ok(none(vec![(session.clone(), false)]))
        }
        Work::Train { sets: files } => {
            let spec = models()
                .into_iter()
                .find(|m| m.name == job.name)
                .with_context(|| format!("no model `{}` in the study", job.name))?;
            let loaded;
            let sets = match sets {
                Some(s) => s,
                None => {
                    loaded = load_sets(job, files)?;
                    &loaded
                }
            };
            let outcome = train_and_score(&spec, sets, study)?;
            let model = model_path(study, &job.name);
            let scores = outcome
                .scores
                .into_iter()
                .map(|(object, train, test)| ScoreRow { object: object.into(), train, test })
                .collect();
            Ok(Performed {
                outputs: vec![(model.clone(), false), (path_for(&model), false)],
                summary: outcome.summary,
                scores,
            })
        }
    }
}

/// `OUT/models/NAME.safetensors`.
pub fn model_path(study: &StudySpec, name: &str) -> PathBuf {
    study.out.join("models").join(format!("{name}.safetensors"))
}
