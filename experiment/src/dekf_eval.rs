//! Scoring a dEKF model on sessions against their truth (thesis Table 6.1),
//! beside the zero-motion baseline.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use anyhow::{Result, bail};
use serde::Serialize;
use slidetrack_core::TimeNs;
use slidetrack_estimators::dekf::{DekfModel, DekfOutput};
use slidetrack_session::{ChannelMessage, ProtocolEvent, ReadOptions, SessionInfo};

use crate::dataset::{SessionData, TruthSource, load};
use crate::dekf_run::{CM, Scores, combine_scores, mean_scores, run, score_with_linear};
use crate::linear_baseline::LinearBaseline;
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
    /// Every step of every session pooled ([`pooled_scores`]).
    pub pooled: Scores,
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
    score_outputs_beside(outputs, data, None)
}

/// The index of the scan of the first output in `data`.
pub fn first_step(outputs: &[(TimeNs, DekfOutput)], data: &SessionData) -> Result<usize> {
    let Some((first, _)) = outputs.first() else { bail!("{}: the dEKF made no step", data.path.display()) };
    Ok(data.times.iter().position(|t| t == first).unwrap_or(0))
}

/// [`score_outputs`] beside the linear-map baseline's predictions on the
/// same session (from the first output's scan), scored on the same steps.
pub fn score_outputs_beside(
    outputs: &[(TimeNs, DekfOutput)],
    data: &SessionData,
    linear: Option<&LinearBaseline>,
) -> Result<Scores> {
    let Some(truth) = &data.truth else { bail!("{} has no truth to score against", data.path.display()) };
    let start = first_step(outputs, data)?;
    let dim = data.truth_dim;
    let origin = truth[start * dim];
    let index: HashMap<u64, usize> = data.times.iter().enumerate().map(|(i, t)| (t.0, i)).collect();
    let predicted: Option<HashMap<u64, Vec<f64>>> = linear
        .map(|b| b.predict(data, start).map(|p| p.into_iter().map(|(t, x)| (t.0, x)).collect()))
        .transpose()?;
    let mut est = Vec::with_capacity(outputs.len());
    let mut tru = Vec::with_capacity(outputs.len());
    let mut lin = Vec::with_capacity(outputs.len());
    for (t, o) in outputs {
        if let Some(&i) = index.get(&t.0) {
            est.push([o.mean[0], o.mean[1]]);
            tru.push([(truth[i * dim] - origin) * CM, truth[i * dim + 1] * CM]);
            // A step the baseline has no row for (never, on the same scans)
            // counts as predicting no motion.
            let l = predicted.as_ref().and_then(|p| p.get(&t.0));
            lin.push(l.map_or([0.0; 2], |x| [x[0], x[1]]));
        }
    }
    Ok(score_with_linear(&est, &tru, predicted.is_some().then_some(&lin[..])))
}

/// Evaluates `model` on `files` against `truth`: each session replayed
/// through the replay rig, as `track` would have run the model live.
/// With `linear`, the linear-map baseline is scored beside it on the same steps.
pub fn evaluate(
    model: &DekfModel,
    files: &[PathBuf],
    truth: TruthSource,
    linear: Option<&LinearBaseline>,
) -> Result<EvalReport> {
    let mut sessions = Vec::new();
    for f in files {
        let data = load(f, Some(truth))?;
        let outputs = dekf_outputs(model, f, &data)?;
        let main = score_outputs_beside(&outputs, &data, linear)?;
        let sim = if truth != TruthSource::Sim {
            match load(f, Some(TruthSource::Sim)) {
                Ok(d) => Some(score_outputs_beside(&outputs, &d, linear)?),
                Err(_) => None,
            }
        } else {
            None
        };
        sessions.push(SessionScores { file: f.display().to_string(), scores: main, sim });
    }
    let all: Vec<Scores> = sessions.iter().map(|s| s.scores.clone()).collect();
    let (mean, pooled) = (mean_scores(&all), pooled_scores(&all));
    let sims: Vec<Scores> = sessions.iter().filter_map(|s| s.sim.clone()).collect();
    Ok(EvalReport {
        mean,
        pooled,
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

/// A cell of an optional score.
fn opt(v: Option<f64>) -> String {
    v.map_or_else(|| "-".into(), |v| format!("{v:.3}"))
}

fn row(name: &str, s: &Scores) -> String {
    format!(
        "{name:<34} {:>8.3} {:>8.3} {:>9.3} {:>9.3} {:>8.3} {:>8.3} {:>8} {:>8}",
        s.position_rmse_cm,
        s.position_max_cm,
        s.velocity_rmse_cmps,
        s.velocity_max_cmps,
        s.baseline_position_rmse_cm,
        s.baseline_velocity_rmse_cmps,
        opt(s.linear_position_rmse_cm),
        opt(s.linear_velocity_rmse_cmps),
    )
}

/// The scores of all steps of `sessions` pooled: the root of the mean of
/// every squared error (maxima: the largest).
pub fn pooled_scores(sessions: &[Scores]) -> Scores {
    combine_scores(
        sessions,
        |v| {
            let steps: usize = v.iter().map(|(_, k)| k).sum();
            (v.iter().map(|(x, k)| x * x * *k as f64).sum::<f64>() / steps.max(1) as f64).sqrt()
        },
        |v| v.iter().copied().fold(0.0, f64::max),
    )
}

/// The report as a table: the dEKF beside predicting no motion (`zero`:
/// position 0, velocity 0) and the linear-map baseline (`linear`, `-`
/// without one) on the same steps.
pub fn table(r: &EvalReport) -> String {
    let mut out = format!(
        "against {}\n{:<34} {:>8} {:>8} {:>9} {:>9} {:>8} {:>8} {:>8} {:>8}\n{:<34} {:>8} {:>8} {:>9} {:>9} {:>8} {:>8} {:>8} {:>8}\n",
        r.against,
        "session",
        "pos RMSE",
        "pos max",
        "vel RMSE",
        "vel max",
        "zero pos",
        "zero vel",
        "lin pos",
        "lin vel",
        "",
        "(cm)",
        "(cm)",
        "(cm/s)",
        "(cm/s)",
        "(cm)",
        "(cm/s)",
        "(cm)",
        "(cm/s)"
    );
    for s in &r.sessions {
        let name =
            Path::new(&s.file).file_name().map_or(s.file.clone(), |n| n.to_string_lossy().into_owned());
        out += &row(&name, &s.scores);
        out.push('\n');
    }
    out += &row("MEAN", &r.mean);
    out.push('\n');
    out += &row("POOLED", &r.pooled);
    out.push('\n');
    if let Some(sim) = &r.sim {
        out += &row("MEAN against /sim/truth", sim);
        out.push('\n');
    }
    out
}
