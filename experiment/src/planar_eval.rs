//! Scoring a planar dEKF model on sessions against `/ground_truth/planar`,
//! beside predicting no motion and the linear-map baseline on the same
//! steps: in-plane translation of the grip point (mm, the norm of the 2-D
//! error), rotation about the contact normal (deg), and their rates.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use anyhow::{Result, bail};
use serde::Serialize;
use slidetrack_core::TimeNs;
use slidetrack_estimators::dekf::{DekfModel, DekfOutput, StateKind};

use crate::dataset::{SessionData, TruthSource, load_unless_short};
use crate::dekf_eval::first_step;
use crate::dekf_run::{model_units, run};
use crate::linear_baseline::LinearBaseline;

/// Errors of one estimator on the planar state (mm, deg, mm/s, deg/s).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct PlanarErrors {
    /// RMSE of the in-plane translation (mm): the root of the mean squared
    /// norm of the 2-D error.
    pub translation_rmse_mm: f64,
    /// RMSE of the rotation about the contact normal (deg).
    pub rotation_rmse_deg: f64,
    /// RMSE of the in-plane velocity (mm/s, norm of the 2-D error).
    pub velocity_rmse_mmps: f64,
    /// RMSE of the angular velocity about the normal (deg/s).
    pub angular_velocity_rmse_degps: f64,
}

/// Squared-error sums of one estimator over a set of steps.
#[derive(Clone, Copy, Debug, Default)]
struct Sums {
    sq: [f64; 4],
    steps: usize,
}

impl Sums {
    fn add(&mut self, est: &[f64], truth: &[f64]) {
        let e: Vec<f64> = est.iter().zip(truth).map(|(a, b)| a - b).collect();
        self.sq[0] += e[0] * e[0] + e[1] * e[1];
        self.sq[1] += e[2] * e[2];
        self.sq[2] += e[3] * e[3] + e[4] * e[4];
        self.sq[3] += e[5] * e[5];
        self.steps += 1;
    }

    fn merge(&mut self, o: &Sums) {
        for i in 0..4 {
            self.sq[i] += o.sq[i];
        }
        self.steps += o.steps;
    }

    fn errors(&self) -> PlanarErrors {
        let r = |i: usize| (self.sq[i] / self.steps.max(1) as f64).sqrt();
        PlanarErrors {
            translation_rmse_mm: r(0),
            rotation_rmse_deg: r(1),
            velocity_rmse_mmps: r(2),
            angular_velocity_rmse_degps: r(3),
        }
    }
}

/// The scores of one session or of a pool of them.
#[derive(Clone, Debug, Default, Serialize)]
pub struct PlanarScores {
    /// The dEKF.
    pub dekf: PlanarErrors,
    /// Predicting no motion: translation and rotation 0 (relative to the
    /// first step), velocities 0.
    pub zero: PlanarErrors,
    /// The linear-map baseline, when there is one.
    pub linear: Option<PlanarErrors>,
    /// Largest translation error of the dEKF (mm).
    pub translation_max_mm: f64,
    /// Largest rotation error of the dEKF (deg).
    pub rotation_max_deg: f64,
    /// Filter steps compared.
    pub steps: usize,
}

/// One session's scores.
#[derive(Clone, Debug, Serialize)]
pub struct PlanarSessionScores {
    /// The file.
    pub file: String,
    /// Its scores.
    #[serde(flatten)]
    pub scores: PlanarScores,
}

/// How many sessions the dEKF beats a baseline on.
#[derive(Clone, Copy, Debug, Default, Serialize)]
pub struct Wins {
    /// Translation RMSE below the baseline's.
    pub translation: usize,
    /// Rotation RMSE below the baseline's.
    pub rotation: usize,
    /// Both.
    pub both: usize,
    /// Sessions scored.
    pub sessions: usize,
}

/// A planar model's scores on several sessions.
#[derive(Clone, Debug, Serialize)]
pub struct PlanarReport {
    /// The truth scored against.
    pub against: String,
    /// Every step of every session pooled (root of the mean of all squared errors).
    pub pooled: PlanarScores,
    /// The mean of the sessions' RMSEs.
    pub mean: PlanarScores,
    /// Sessions on which the dEKF beats predicting no motion.
    pub beats_zero: Wins,
    /// Sessions on which the dEKF beats the linear map (when there is one).
    pub beats_linear: Option<Wins>,
    /// Per session.
    pub sessions: Vec<PlanarSessionScores>,
    /// Sessions not scored: fewer than [`crate::dataset::MIN_SCANS`] scans in the hold.
    pub skipped: Vec<String>,
}

/// The three estimators' squared errors on one session, plus the maxima.
struct SessionSums {
    dekf: Sums,
    zero: Sums,
    linear: Option<Sums>,
    max: [f64; 2],
}

impl SessionSums {
    fn scores(&self) -> PlanarScores {
        PlanarScores {
            dekf: self.dekf.errors(),
            zero: self.zero.errors(),
            linear: self.linear.map(|l| l.errors()),
            translation_max_mm: self.max[0],
            rotation_max_deg: self.max[1],
            steps: self.dekf.steps,
        }
    }
}

/// Squared errors of the dEKF's `outputs`, of no motion and of `linear` on
/// `data` (loaded with the planar truth), in the model's units, positions
/// relative to the first output's scan.
fn session_sums(
    outputs: &[(TimeNs, DekfOutput)],
    data: &SessionData,
    linear: Option<&LinearBaseline>,
) -> Result<SessionSums> {
    if data.truth_dim != 6 {
        bail!("{}: a planar model is scored against the planar truth", data.path.display());
    }
    let start = first_step(outputs, data)?;
    let units = model_units(6);
    let to_model = |k: usize, origin: &[f64]| -> Option<Vec<f64>> {
        let x = data.truth_at(k)?;
        Some((0..6).map(|i| if i < 3 { (x[i] - origin[i]) * units[i] } else { x[i] * units[i] }).collect())
    };
    let Some(origin) = data.truth_at(start).map(<[f64]>::to_vec) else {
        bail!("{} has no truth to score against", data.path.display())
    };
    let index: HashMap<u64, usize> = data.times.iter().enumerate().map(|(i, t)| (t.0, i)).collect();
    let predicted: Option<HashMap<u64, Vec<f64>>> = linear
        .map(|b| b.predict(data, start).map(|p| p.into_iter().map(|(t, x)| (t.0, x)).collect()))
        .transpose()?;
    let mut sums = SessionSums {
        dekf: Sums::default(),
        zero: Sums::default(),
        linear: predicted.as_ref().map(|_| Sums::default()),
        max: [0.0; 2],
    };
    let zero = [0.0; 6];
    for (t, o) in outputs {
        let Some(truth) = index.get(&t.0).and_then(|&k| to_model(k, &origin)) else { continue };
        // No truth where the marker was not seen for long.
        if !truth.iter().all(|v| v.is_finite()) {
            continue;
        }
        sums.dekf.add(&o.mean, &truth);
        sums.zero.add(&zero, &truth);
        if let (Some(l), Some(p)) = (sums.linear.as_mut(), predicted.as_ref()) {
            l.add(p.get(&t.0).map_or(&zero[..], |x| &x[..]), &truth);
        }
        let (dx, dy) = (o.mean[0] - truth[0], o.mean[1] - truth[1]);
        sums.max[0] = sums.max[0].max(dx.hypot(dy));
        sums.max[1] = sums.max[1].max((o.mean[2] - truth[2]).abs());
    }
    Ok(sums)
}

fn wins(sessions: &[PlanarSessionScores], baseline: fn(&PlanarScores) -> Option<PlanarErrors>) -> Wins {
    let mut w = Wins { sessions: sessions.len(), ..Wins::default() };
    for s in sessions {
        let Some(b) = baseline(&s.scores) else { continue };
        let t = s.scores.dekf.translation_rmse_mm < b.translation_rmse_mm;
        let r = s.scores.dekf.rotation_rmse_deg < b.rotation_rmse_deg;
        w.translation += usize::from(t);
        w.rotation += usize::from(r);
        w.both += usize::from(t && r);
    }
    w
}

fn mean_errors(all: &[PlanarErrors]) -> PlanarErrors {
    let n = all.len().max(1) as f64;
    let avg = |f: fn(&PlanarErrors) -> f64| all.iter().map(f).sum::<f64>() / n;
    PlanarErrors {
        translation_rmse_mm: avg(|e| e.translation_rmse_mm),
        rotation_rmse_deg: avg(|e| e.rotation_rmse_deg),
        velocity_rmse_mmps: avg(|e| e.velocity_rmse_mmps),
        angular_velocity_rmse_degps: avg(|e| e.angular_velocity_rmse_degps),
    }
}

/// Scores the planar `model` on `files` against `/ground_truth/planar`: the
/// dEKF run over each session's hold (the scans its planar truth covers),
/// beside no motion and `linear` on the same steps.
pub fn evaluate_planar(
    model: &DekfModel,
    files: &[PathBuf],
    linear: Option<&LinearBaseline>,
) -> Result<PlanarReport> {
    if model.state() != StateKind::Planar {
        bail!("evaluate_planar needs a planar model, not a {} one", model.state());
    }
    let (mut pooled, mut pooled_zero, mut pooled_linear) = (Sums::default(), Sums::default(), None::<Sums>);
    let mut max = [0.0f64; 2];
    let (mut sessions, mut skipped) = (Vec::new(), Vec::new());
    for f in files {
        let Some(data) = load_unless_short(f, Some(TruthSource::Planar))? else {
            skipped.push(f.display().to_string());
            continue;
        };
        let s = session_sums(&run(model, &data)?, &data, linear)?;
        pooled.merge(&s.dekf);
        pooled_zero.merge(&s.zero);
        if let Some(l) = &s.linear {
            pooled_linear.get_or_insert_with(Sums::default).merge(l);
        }
        max = [max[0].max(s.max[0]), max[1].max(s.max[1])];
        sessions.push(PlanarSessionScores { file: f.display().to_string(), scores: s.scores() });
    }
    let of = |f: fn(&PlanarScores) -> PlanarErrors| {
        mean_errors(&sessions.iter().map(|s| f(&s.scores)).collect::<Vec<_>>())
    };
    let linear_means: Option<Vec<PlanarErrors>> = sessions.iter().map(|s| s.scores.linear).collect();
    let n = sessions.len().max(1) as f64;
    let mean = PlanarScores {
        dekf: of(|s| s.dekf),
        zero: of(|s| s.zero),
        linear: linear_means.filter(|v| !v.is_empty()).map(|v| mean_errors(&v)),
        translation_max_mm: sessions.iter().map(|s| s.scores.translation_max_mm).sum::<f64>() / n,
        rotation_max_deg: sessions.iter().map(|s| s.scores.rotation_max_deg).sum::<f64>() / n,
        steps: pooled.steps,
    };
    let pooled = PlanarScores {
        dekf: pooled.errors(),
        zero: pooled_zero.errors(),
        linear: pooled_linear.map(|l| l.errors()),
        translation_max_mm: max[0],
        rotation_max_deg: max[1],
        steps: pooled.steps,
    };
    Ok(PlanarReport {
        against: TruthSource::Planar.topic().into(),
        beats_zero: wins(&sessions, |s| Some(s.zero)),
        beats_linear: pooled.linear.map(|_| wins(&sessions, |s| s.linear)),
        pooled,
        mean,
        sessions,
        skipped,
    })
}

fn row(name: &str, s: &PlanarScores) -> String {
    let l = |f: fn(&PlanarErrors) -> f64| {
        s.linear.as_ref().map_or_else(|| "-".into(), |e| format!("{:.3}", f(e)))
    };
    format!(
        "{name:<34} {:>8.3} {:>8.3} {:>8} {:>8.3} {:>8.3} {:>8} {:>8.3} {:>8.3} {:>6}",
        s.dekf.translation_rmse_mm,
        s.zero.translation_rmse_mm,
        l(|e| e.translation_rmse_mm),
        s.dekf.rotation_rmse_deg,
        s.zero.rotation_rmse_deg,
        l(|e| e.rotation_rmse_deg),
        s.dekf.velocity_rmse_mmps,
        s.dekf.angular_velocity_rmse_degps,
        s.steps
    )
}

/// The report as a table: translation and rotation RMSE of the dEKF, of no
/// motion and of the linear map (`-` without one), the dEKF's rate errors.
pub fn planar_table(r: &PlanarReport) -> String {
    let mut out = format!(
        "against {}\n{:<34} {:>8} {:>8} {:>8} {:>8} {:>8} {:>8} {:>8} {:>8} {:>6}\n{:<34} {:>8} {:>8} {:>8} {:>8} {:>8} {:>8} {:>8} {:>8} {:>6}\n",
        r.against,
        "session",
        "transl",
        "zero",
        "linear",
        "rot",
        "zero",
        "linear",
        "vel",
        "ang vel",
        "steps",
        "",
        "(mm)",
        "(mm)",
        "(mm)",
        "(deg)",
        "(deg)",
        "(deg)",
        "(mm/s)",
        "(deg/s)",
        ""
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
    let ratio = |a: f64, b: f64| 100.0 * a / b.max(1e-12);
    let p = &r.pooled;
    out += &format!(
        "pooled: translation {:.0} % of zero motion, rotation {:.0} %",
        ratio(p.dekf.translation_rmse_mm, p.zero.translation_rmse_mm),
        ratio(p.dekf.rotation_rmse_deg, p.zero.rotation_rmse_deg)
    );
    if let Some(l) = &p.linear {
        out += &format!(
            "; of the linear map: {:.0} % and {:.0} %",
            ratio(p.dekf.translation_rmse_mm, l.translation_rmse_mm),
            ratio(p.dekf.rotation_rmse_deg, l.rotation_rmse_deg)
        );
    }
    let z = &r.beats_zero;
    out += &format!(
        "\nbetter than zero motion on {} of {} sessions in translation, {} in rotation, {} in both\n",
        z.translation, z.sessions, z.rotation, z.both
    );
    for s in &r.skipped {
        out += &format!("skipped (fewer than {} scans in the hold): {s}\n", crate::dataset::MIN_SCANS);
    }
    out
}
