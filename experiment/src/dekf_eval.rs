//! Scoring a dEKF model on sessions against their truth (thesis Table 6.1),
//! beside the zero-motion baseline.

use std::path::{Path, PathBuf};

use anyhow::{Result, bail};
use serde::Serialize;
use slidetrack_core::TimeNs;
use slidetrack_estimators::dekf::{DekfModel, DekfOutput};
use slidetrack_session::{ChannelMessage, ProtocolEvent, ReadOptions, SessionInfo};

use crate::dataset::{SessionData, TruthSource, load};
use crate::dekf_run::{CM, Scores, mean_scores, run, score};
use crate::replay::replay_dekf;

/// The scores of one session.
#[derive(Clone, Debug, Serialize)]
pub struct SessionScores {
    /// The file.
    pub file: String,
    /// Against the chosen truth.
    #[serde(flatten)]
    pub scores: Scores,
    /// Against `/sim/truth`, when the session has it and the chosen truth is another.
    pub sim: Option<Scores>,
}

/// Scores of a model on several sessions.
#[derive(Clone, Debug, Serialize)]
pub struct EvalReport {
    /// Averages over sessions.
    #[serde(flatten)]
    pub mean: Scores,
    /// The truth scored against.
    pub against: String,
    /// Averages against `/sim/truth` over the sessions that have it.
    pub sim: Option<Scores>,
    /// Per session.
    pub sessions: Vec<SessionScores>,
}

/// Scores of `model` on one session against `truth` (relative to the first step).
pub fn score_session(model: &DekfModel, data: &SessionData) -> Result<Scores> {
    score_outputs(&run(model, data)?, data)
}

/// Scores the estimates `outputs` of a run over `data`'s session against
/// its truth: the steps before the release, positions relative to the first.
pub fn score_outputs(outputs: &[(TimeNs, DekfOutput)], data: &SessionData) -> Result<Scores> {
    let Some(truth) = &data.truth else { bail!("{} has no truth to score against", data.path.display()) };
    let Some((first, _)) = outputs.first() else { bail!("{}: the dEKF made no step", data.path.display()) };
    let start = data.times.iter().position(|t| t == first).unwrap_or(0);
    let origin = truth[start][0];
    let index: std::collections::HashMap<u64, usize> =
        data.times.iter().enumerate().map(|(i, t)| (t.0, i)).collect();
    let mut est = Vec::with_capacity(outputs.len());
    let mut tru = Vec::with_capacity(outputs.len());
    for (t, o) in outputs {
        if let Some(&i) = index.get(&t.0) {
            est.push([o.mean[0], o.mean[1]]);
            tru.push([(truth[i][0] - origin) * CM, truth[i][1] * CM]);
        }
    }
    Ok(score(&est, &tru))
}

/// Evaluates `model` on `files` against `truth`: each session replayed
/// through the replay rig, as `track` would have run the model live.
pub fn evaluate(model: &DekfModel, files: &[PathBuf], truth: TruthSource) -> Result<EvalReport> {
    let mut sessions = Vec::new();
    for f in files {
        let data = load(f, Some(truth))?;
        let outputs = dekf_outputs(model, f, &data)?;
        let main = score_outputs(&outputs, &data)?;
        let sim = if truth != TruthSource::Sim {
            match load(f, Some(TruthSource::Sim)) {
                Ok(d) => Some(score_outputs(&outputs, &d)?),
                Err(_) => None,
            }
        } else {
            None
        };
        sessions.push(SessionScores { file: f.display().to_string(), scores: main, sim });
    }
    let mean = mean_scores(&sessions.iter().map(|s| s.scores.clone()).collect::<Vec<_>>());
    let sims: Vec<Scores> = sessions.iter().filter_map(|s| s.sim.clone()).collect();
    Ok(EvalReport {
        mean,
        against: truth.topic().into(),
        sim: (!sims.is_empty()).then(|| mean_scores(&sims)),
        sessions,
    })
}

/// The estimates of `model` on the session at `path` (loaded as `data`):
/// replayed through the replay rig as `track` would have run it live, or,
/// on sessions recorded without the protocol (imports of recordings made
/// elsewhere, which have nothing to replay it on), run over their recorded
/// baseline-subtracted scans through the same stage.
pub fn dekf_outputs(model: &DekfModel, path: &Path, data: &SessionData) -> Result<Vec<(TimeNs, DekfOutput)>> {
    if has_protocol(path)? { replay_dekf(path, model) } else { run(model, data) }
}

/// True when the session at `path` recorded the protocol's events.
pub fn has_protocol(path: &Path) -> Result<bool> {
    let info = SessionInfo::read(path, ReadOptions::default())?;
    Ok(info.channel(ProtocolEvent::TOPIC).is_some())
}

fn row(name: &str, s: &Scores) -> String {
    format!(
        "{name:<34} {:>8.3} {:>8.3} {:>9.3} {:>9.3} {:>10.3}",
        s.position_rmse_cm,
        s.position_max_cm,
        s.velocity_rmse_cmps,
        s.velocity_max_cmps,
        s.baseline_position_rmse_cm
    )
}

/// The report as a table.
pub fn table(r: &EvalReport) -> String {
    let mut out = format!(
        "against {}\n{:<34} {:>8} {:>8} {:>9} {:>9} {:>10}\n{:<34} {:>8} {:>8} {:>9} {:>9} {:>10}\n",
        r.against,
        "session",
        "pos RMSE",
        "pos max",
        "vel RMSE",
        "vel max",
        "baseline",
        "",
        "(cm)",
        "(cm)",
        "(cm/s)",
        "(cm/s)",
        "pos (cm)"
    );
    for s in &r.sessions {
        let name =
            Path::new(&s.file).file_name().map_or(s.file.clone(), |n| n.to_string_lossy().into_owned());
        out += &row(&name, &s.scores);
        out.push('\n');
    }
    out += &row("MEAN", &r.mean);
    out.push('\n');
    if let Some(sim) = &r.sim {
        out += &row("MEAN against /sim/truth", sim);
        out.push('\n');
    }
    out
}
