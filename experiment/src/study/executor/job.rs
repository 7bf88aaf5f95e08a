//! The study's jobs and their results, as the work directory holds them:
//! `STAGE/jobs/NN-NAME.json` ([`Job`]) and `STAGE/results/NN-NAME.json`
//! ([`JobResult`]). A job is one trial to collect, one session to label or
//! one model to train and score ([`Work`]).

use std::path::PathBuf;

use serde::{Deserialize, Serialize};
use serde_json::Value;

use super::stored::{optional_scores, scores};
use crate::dekf_run::Scores;
use crate::protocol::Protocol;
use crate::study::StudySpec;

/// The session files of one object's training or testing set.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SetFiles {
    /// The object.
    pub object: String,
    /// The testing set (`true`) or the training set.
    pub testing: bool,
    /// Its sessions, in the order the study reads them.
    pub files: Vec<PathBuf>,
}

/// What a job does; its inputs and outputs are files named here or in the
/// study's settings.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Work {
    /// Simulates trial `trial` of `object` into `session` (what
    /// `slidetrack collect` does for one trial; the seed and duration are
    /// the study's). Output: `session`.
    Collect {
        /// The object.
        object: String,
        /// The trial number.
        trial: u32,
        /// The session file it writes (`OBJECT-sSEED-tTTT.mcap` in the
        /// study's sessions directory).
        session: PathBuf,
    },
    /// Labels `session` in place with `protocol`'s ground truth (what
    /// `slidetrack label` does for one file); a session that already has
    /// the study's truth is left as it is. Input and output: `session`.
    Label {
        /// The labelling protocol.
        protocol: Protocol,
        /// The session file.
        session: PathBuf,
    },
    /// Trains one model of the study and scores it. Inputs: the sets'
    /// sessions; outputs: the model and its linear baseline in `OUT/models`.
    Train {
        /// The sets it reads.
        sets: Vec<SetFiles>,
    },
}

/// One job of a stage of the study.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Job {
    /// Its index in the stage's plan (the array task id under Slurm).
    pub index: usize,
    /// Its name: the model's, or the session's file stem.
    pub name: String,
    /// Cores it uses.
    pub threads: usize,
    /// The study's settings (`threads` 1: results do not depend on it).
    pub study: StudySpec,
    /// What it does.
    #[serde(flatten)]
    pub work: Work,
}

/// One scored object of a training job's result.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct ScoreRow {
    /// The tested object.
    pub object: String,
    /// Scores on its training set (Table 6.1 only).
    #[serde(with = "optional_scores")]
    pub train: Option<Scores>,
    /// Scores on its testing set.
    #[serde(with = "scores")]
    pub test: Scores,
}

/// A file a job wrote.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct OutputFile {
    /// The file.
    pub path: PathBuf,
    /// Its SHA-256 when the job finished.
    pub sha256: String,
    /// A later stage rewrites it (a collected session that labelling
    /// writes its ground truth into): the output counts while the file
    /// exists, whatever its SHA-256.
    #[serde(default)]
    pub rewritten_later: bool,
}

/// What a job leaves in `STAGE/results/`: valid while the job file and the
/// output files still have the recorded SHA-256.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct JobResult {
    /// The job's name.
    pub name: String,
    /// SHA-256 of the job file it ran.
    pub job_sha256: String,
    /// The files it wrote.
    pub outputs: Vec<OutputFile>,
    /// A training job's summary of its model in `tables.json` (`null` otherwise).
    pub summary: Value,
    /// A training job's scores (empty otherwise).
    pub scores: Vec<ScoreRow>,
    /// Host that ran it.
    pub host: String,
    /// The Slurm task that ran it (`ARRAYJOB_TASK`); `None` outside Slurm.
    #[serde(default)]
    pub slurm_task: Option<String>,
    /// When it started (s since the Unix epoch).
    pub started_unix_s: f64,
    /// When it finished (s since the Unix epoch).
    pub finished_unix_s: f64,
}
