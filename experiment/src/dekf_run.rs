//! The dEKF on sessions: the inputs a model reads, running a model over a
//! session, and scoring its estimates (thesis Sec. 3.4.1, Table 6.1).

use std::collections::BTreeMap;
use std::path::Path;

use anyhow::{Context, Result, bail};
use serde::Serialize;
use slidetrack_core::{TactileInfo, TimeNs};
use slidetrack_estimators::dekf::{
    DekfInput, DekfModel, DekfOutput, DekfTracker, Measurement, Sequence, StateKind,
};
use slidetrack_estimators::derivative::DerivativeFilterConfig;
use slidetrack_estimators::metrics::RunningRms;
use slidetrack_session::{
    ChannelHandle, DERIVATIVE_CHANNELS_KEY, DekfEstimate, Logger, NewChannel, PlanarEstimate, PlanarState,
    SlidingEstimate,
};

use crate::channels::ChannelPicker;
use crate::dataset::SessionData;

/// Metres to centimetres.
pub const CM: f64 = 100.0;
/// Radians to degrees.
pub const DEG: f64 = 180.0 / std::f64::consts::PI;

/// The factors from a truth sample's SI units to a model's state units, per
/// component ([`StateKind::from_si`]): cm and cm/s for the sliding state
/// (2 components); mm, deg, mm/s and deg/s for the planar one (6).
pub fn model_units(dim: usize) -> Vec<f64> {
    if dim == 6 { StateKind::Planar.from_si() } else { vec![CM; dim] }
}

/// The model inputs of a session at the filter rate.
pub struct Inputs {
    /// Times of the filter steps (every `decimation`-th scan from the first).
    pub times: Vec<TimeNs>,
    /// Unnormalised measurement per step, model channel order.
    pub measurements: Vec<Vec<f64>>,
    /// Truth per step in the model's state units (cm, cm/s; planar: mm,
    /// deg, mm/s, deg/s), positions relative to the first step,
    /// `truth_dim` components each, step after step.
    pub truth: Option<Vec<f64>>,
    /// Components of one truth sample (2 sliding, 6 planar).
    pub truth_dim: usize,
}

impl Inputs {
    /// The truth at step `k`, when there is one.
    pub fn truth_at(&self, k: usize) -> Option<&[f64]> {
        self.truth.as_ref().map(|t| &t[k * self.truth_dim..(k + 1) * self.truth_dim])
    }
}

/// The filter-rate inputs of `session` for the given channels and
/// measurement, through the online filter's own input pipeline ([`DekfInput`]).
pub fn inputs(
    session: &SessionData,
    channels: &[String],
    measurement: Measurement,
    filter: DerivativeFilterConfig,
    decimation: usize,
) -> Result<Inputs> {
    let picker = ChannelPicker::new(channels, &session.tactile)
        .with_context(|| format!("{}: the channels {}", session.path.display(), channels.join(", ")))?;
    let mut input = DekfInput::new(measurement, filter, picker.len(), decimation);
    let dim = session.truth_dim;
    let mut out = Inputs {
        times: Vec::new(),
        measurements: Vec::new(),
        truth: session.truth.as_ref().map(|_| Vec::new()),
        truth_dim: dim,
    };
    let units = model_units(dim);
    let origin: Option<Vec<f64>> = session.truth_at(0).map(<[f64]>::to_vec);
    let mut values = vec![0.0; picker.len()];
    for (k, (t, z)) in session.times.iter().zip(session.scans()).enumerate() {
        picker.pick(z, &mut values);
        let Some(step) = input.on_scan(t.as_secs_f64(), &values) else { continue };
        out.times.push(*t);
        out.measurements.push(step.measurement);
        if let (Some(truth), Some(x), Some(o)) = (out.truth.as_mut(), session.truth_at(k), origin.as_ref()) {
            // Positions relative to the first step, rates as they are.
            truth.extend(
                (0..dim).map(|i| if i < dim / 2 { (x[i] - o[i]) * units[i] } else { x[i] * units[i] }),
            );
        }
    }
    Ok(out)
}

/// Per-channel mean and standard deviation of the finite measurements.
pub fn normalisation(all: &[&Inputs], channels: usize) -> (Vec<f32>, Vec<f32>) {
    let mut sum = vec![0.0f64; channels];
    let mut sq = vec![0.0f64; channels];
    let mut n = vec![0usize; channels];
    for inp in all {
        for m in &inp.measurements {
            for (c, v) in m.iter().enumerate() {
                if v.is_finite() {
                    sum[c] += v;
                    sq[c] += v * v;
                    n[c] += 1;
                }
            }
        }
    }
    let mean: Vec<f64> = (0..channels).map(|c| sum[c] / n[c].max(1) as f64).collect();
    let std = (0..channels)
        .map(|c| ((sq[c] / n[c].max(1) as f64 - mean[c] * mean[c]).max(0.0)).sqrt() as f32)
        .collect();
    (mean.iter().map(|m| *m as f32).collect(), std)
}

/// A training sequence from `inputs`, normalised with `model`'s normalisation.
pub fn sequence(model: &DekfModel, inputs: &Inputs) -> Result<Sequence> {
    let truth = inputs.truth.clone().context("a training session needs its truth")?;
    let dim = model.state().dim();
    if inputs.truth_dim != dim {
        bail!("a {} model needs a truth of {dim} components, not {}", model.state(), inputs.truth_dim);
    }
    let c = model.layout.channels;
    let mut measurements = Vec::with_capacity(inputs.measurements.len() * c);
    let mut valid = Vec::with_capacity(inputs.measurements.len());
    for m in &inputs.measurements {
        let mut v: Vec<f32> = m.iter().map(|x| *x as f32).collect();
        let ok = v.iter().all(|x| x.is_finite());
        model.normalise(&mut v);
        measurements.extend(v.iter().map(|x| if x.is_finite() { *x } else { 0.0 }));
        valid.push(ok);
    }
    Ok(Sequence { measurements, valid, truth, dim })
}

/// Default largest relative difference between a session's tactile rate and
/// the model's.
pub const DEFAULT_RATE_TOLERANCE: f64 = 0.05;
/// Key of the model's training metadata holding a rate tolerance other than
/// [`DEFAULT_RATE_TOLERANCE`] (`train --rate-tolerance`).
pub const RATE_TOLERANCE_KEY: &str = "rate_tolerance";

/// The largest relative difference between a session's tactile rate and
/// `model`'s that it was trained to accept.
pub fn rate_tolerance(model: &DekfModel) -> f64 {
    model
        .meta
        .training
        .get(RATE_TOLERANCE_KEY)
        .and_then(serde_json::Value::as_f64)
        .unwrap_or(DEFAULT_RATE_TOLERANCE)
}

/// Checks that `model` can run on `session`.
pub fn check_compatible(model: &DekfModel, session: &SessionData) -> Result<()> {
    ChannelPicker::new(&model.meta.channels, &session.tactile).with_context(|| {
        format!("{}: the model's channels do not match the session's tactile sensors", session.path.display())
    })?;
    let expected = model.meta.tactile_rate_hz;
    if (session.rate_hz - expected).abs() > rate_tolerance(model) * expected {
        bail!(
            "{}: tactile rate {:.1} Hz, but the model was trained at {:.1} Hz (decimation {})",
            session.path.display(),
            session.rate_hz,
            expected,
            model.meta.decimation
        );
    }
    Ok(())
}

/// The dEKF on a stream of baseline-subtracted scans: the model's channels
/// picked from each scan, then the online tracker (its input pipeline and
/// filter). Live tracking, replays and scoring all step the dEKF through it.
pub struct DekfStage {
    tracker: DekfTracker,
    channels: ChannelPicker,
    values: Vec<f64>,
}

impl DekfStage {
    /// The stage of `model` on scans of `tactile`; fails when the model's
    /// channels do not resolve against its layout.
    pub fn new(model: &DekfModel, tactile: &TactileInfo) -> Result<DekfStage> {
        let channels = ChannelPicker::new(&model.meta.channels, tactile)?;
        Ok(DekfStage { tracker: DekfTracker::new(model), values: vec![0.0; channels.len()], channels })
    }

    /// One scan at `t`: the baseline-subtracted values of every taxel
    /// (counts, layout order). Returns the estimate at filter steps.
    pub fn on_scan(&mut self, t: TimeNs, zeroed: &[[f64; 3]]) -> Option<DekfOutput> {
        self.channels.pick(zeroed, &mut self.values);
        self.tracker.on_scan(t.as_secs_f64(), &self.values)
    }
}

/// Runs `model` over `session`'s recorded scans from the first: the
/// estimates of every filter step with their scan times (the training's
/// epoch selection; sessions are replayed through [`crate::replay`]).
pub fn run(model: &DekfModel, session: &SessionData) -> Result<Vec<(TimeNs, DekfOutput)>> {
    check_compatible(model, session)?;
    let mut stage = DekfStage::new(model, &session.tactile)?;
    Ok(session
        .times
        .iter()
        .zip(session.scans())
        .filter_map(|(t, z)| Some((*t, stage.on_scan(*t, z)?)))
        .collect())
}

/// The `/estimate/dekf` message of a dEKF output (cm -> m).
pub fn estimate_message(o: &DekfOutput) -> DekfEstimate {
    let s = 1.0 / CM;
    let c = |r, k| o.cov_at(r, k) * s * s;
    DekfEstimate(SlidingEstimate {
        position: o.mean[0] * s,
        velocity: o.mean[1] * s,
        covariance: [[c(0, 0), c(0, 1)], [c(1, 0), c(1, 1)]],
    })
}

/// The `/estimate/dekf_planar` message of a planar model's output (mm ->
/// m, deg -> rad).
pub fn planar_message(o: &DekfOutput) -> PlanarEstimate {
    let si: Vec<f64> = StateKind::Planar.from_si().iter().map(|f| 1.0 / f).collect();
    let m = |i: usize| o.mean[i] * si[i];
    PlanarEstimate {
        state: PlanarState {
            translation_m: [m(0), m(1)],
            rotation_rad: m(2),
            velocity_m_per_s: [m(3), m(4)],
            angular_velocity_rad_per_s: m(5),
        },
        covariance: (0..36).map(|k| o.cov_at(k / 6, k % 6) * si[k / 6] * si[k % 6]).collect(),
    }
}

/// The estimate channel of a model: `/estimate/dekf` for sliding models,
/// `/estimate/dekf_planar` for planar ones.
pub enum EstimateChannel {
    /// A sliding model's.
    Sliding(ChannelHandle<DekfEstimate>),
    /// A planar model's.
    Planar(ChannelHandle<PlanarEstimate>),
}

impl EstimateChannel {
    /// Registers the channel of `model`'s state on `logger`.
    pub fn register(
        logger: &Logger,
        model: &DekfModel,
        metadata: BTreeMap<String, String>,
    ) -> Result<EstimateChannel> {
        Ok(match model.state() {
            StateKind::Sliding => EstimateChannel::Sliding(logger.register::<DekfEstimate>(metadata)?),
            StateKind::Planar => EstimateChannel::Planar(logger.register::<PlanarEstimate>(metadata)?),
        })
    }

    /// Logs `o` at `t`.
    pub fn log(
        &self,
        logger: &Logger,
        t: TimeNs,
        o: &DekfOutput,
    ) -> Result<(), slidetrack_session::SessionError> {
        match self {
            EstimateChannel::Sliding(ch) => logger.log_json(ch, t, t, 0, &estimate_message(o)),
            EstimateChannel::Planar(ch) => logger.log_json(ch, t, t, 0, &planar_message(o)),
        }
    }
}

/// The estimates of `outputs` as the new channel a rewrite adds: the
/// channel of the model's state.
pub fn estimate_channel(
    model: &DekfModel,
    metadata: BTreeMap<String, String>,
    outputs: &[(TimeNs, DekfOutput)],
) -> Result<NewChannel> {
    let mut ch = match model.state() {
        StateKind::Sliding => NewChannel::of::<DekfEstimate>(metadata),
        StateKind::Planar => NewChannel::of::<PlanarEstimate>(metadata),
    };
    for (t, o) in outputs {
        match model.state() {
            StateKind::Sliding => ch.push_json(*t, &estimate_message(o))?,
            StateKind::Planar => ch.push_json(*t, &planar_message(o))?,
        }
    }
    Ok(ch)
}

/// The channel metadata of `/tactile/derivative` and `/estimate/dekf` for
/// `model` read from the file named `model_name`.
pub fn estimate_metadata(model: &DekfModel, model_name: &str) -> Result<[BTreeMap<String, String>; 2]> {
    let derivative = BTreeMap::from([
        (DERIVATIVE_CHANNELS_KEY.to_string(), serde_json::to_string(&model.meta.channels)?),
        ("model".to_string(), model_name.to_string()),
        ("measurement".to_string(), model.meta.measurement.name().to_string()),
    ]);
    let estimate = BTreeMap::from([("model".to_string(), model_name.to_string())]);
    Ok([derivative, estimate])
}

/// Errors of one session (Table 6.1 metrics), in cm and cm/s.
#[derive(Clone, Debug, Default, PartialEq, Serialize, serde::Deserialize)]
pub struct Scores {
    /// Position RMSE (cm).
    pub position_rmse_cm: f64,
    /// Largest position error (cm).
    pub position_max_cm: f64,
    /// Velocity RMSE (cm/s).
    pub velocity_rmse_cmps: f64,
    /// Largest velocity error (cm/s).
    pub velocity_max_cmps: f64,
    /// Position RMSE of the zero-motion baseline (p = 0) (cm).
    pub baseline_position_rmse_cm: f64,
    /// Velocity RMSE of the zero-motion baseline (v = 0) (cm/s).
    pub baseline_velocity_rmse_cmps: f64,
    /// Position RMSE of the linear-map baseline on the same steps (cm),
    /// `null` without one ([`crate::linear_baseline`]).
    pub linear_position_rmse_cm: Option<f64>,
    /// Velocity RMSE of the linear-map baseline (cm/s), `null` without one.
    pub linear_velocity_rmse_cmps: Option<f64>,
    /// Filter steps compared.
    pub steps: usize,
}

/// Scores estimates `(p, v)` (cm, cm/s) against the truth at the same
/// steps, beside the linear-map baseline's estimates when there are some.
pub fn score_with_linear(estimates: &[[f64; 2]], truth: &[[f64; 2]], linear: Option<&[[f64; 2]]>) -> Scores {
    let mut s = score(estimates, truth);
    if let Some(linear) = linear {
        let [mut p, mut v] = [RunningRms::default(); 2];
        for (e, t) in linear.iter().zip(truth).take(s.steps) {
            p.add(e[0] - t[0]);
            v.add(e[1] - t[1]);
        }
        s.linear_position_rmse_cm = p.rms();
        s.linear_velocity_rmse_cmps = v.rms();
    }
    s
}

/// Scores estimates `(p, v)` (cm, cm/s) against the truth at the same steps.
pub fn score(estimates: &[[f64; 2]], truth: &[[f64; 2]]) -> Scores {
    let n = estimates.len().min(truth.len());
    let mut s = Scores { steps: n, ..Scores::default() };
    let [mut p, mut v, mut base_p, mut base_v] = [RunningRms::default(); 4];
    for (e, t) in estimates.iter().zip(truth).take(n) {
        let (dp, dv) = (e[0] - t[0], e[1] - t[1]);
        p.add(dp);
        v.add(dv);
        base_p.add(t[0]);
        base_v.add(t[1]);
        s.position_max_cm = s.position_max_cm.max(dp.abs());
        s.velocity_max_cmps = s.velocity_max_cmps.max(dv.abs());
    }
    // No steps: zero errors, as a run without steps scored before.
    s.position_rmse_cm = p.rms().unwrap_or(0.0);
    s.velocity_rmse_cmps = v.rms().unwrap_or(0.0);
    s.baseline_position_rmse_cm = base_p.rms().unwrap_or(0.0);
    s.baseline_velocity_rmse_cmps = base_v.rms().unwrap_or(0.0);
    s
}

/// The mean of several sessions' scores (Table 6.1's MEAN row averages sessions).
pub fn mean_scores(all: &[Scores]) -> Scores {
    combine_scores(
        all,
        |v| v.iter().map(|(x, _)| x).sum::<f64>() / v.len() as f64,
        |v| v.iter().sum::<f64>() / v.len().max(1) as f64,
    )
}

/// Several sessions' scores combined: each RMSE by `rmse` over the
/// sessions' `(value, steps)` (the optional ones only when every session
/// has them), each maximum by `max`.
pub fn combine_scores(all: &[Scores], rmse: fn(&[(f64, usize)]) -> f64, max: fn(&[f64]) -> f64) -> Scores {
    let of = |f: fn(&Scores) -> f64| {
        let v: Vec<(f64, usize)> = all.iter().map(|s| (f(s), s.steps)).collect();
        if v.is_empty() { 0.0 } else { rmse(&v) }
    };
    let of_opt = |f: fn(&Scores) -> Option<f64>| {
        let v: Option<Vec<(f64, usize)>> = all.iter().map(|s| f(s).map(|x| (x, s.steps))).collect();
        v.filter(|v| !v.is_empty()).map(|v| rmse(&v))
    };
    let max_of = |f: fn(&Scores) -> f64| max(&all.iter().map(f).collect::<Vec<_>>());
    Scores {
        position_rmse_cm: of(|s| s.position_rmse_cm),
        position_max_cm: max_of(|s| s.position_max_cm),
        velocity_rmse_cmps: of(|s| s.velocity_rmse_cmps),
        velocity_max_cmps: max_of(|s| s.velocity_max_cmps),
        baseline_position_rmse_cm: of(|s| s.baseline_position_rmse_cm),
        baseline_velocity_rmse_cmps: of(|s| s.baseline_velocity_rmse_cmps),
        linear_position_rmse_cm: of_opt(|s| s.linear_position_rmse_cm),
        linear_velocity_rmse_cmps: of_opt(|s| s.linear_velocity_rmse_cmps),
        steps: all.iter().map(|s| s.steps).sum(),
    }
}

/// Reads a model file.
pub fn load_model(path: &Path) -> Result<DekfModel> {
    let bytes = std::fs::read(path).with_context(|| format!("cannot read model {}", path.display()))?;
    slidetrack_estimators::dekf::file::from_bytes(&bytes)
        .with_context(|| format!("invalid model file {}", path.display()))
}

/// Writes a model file atomically (temporary file in the same directory, then rename).
pub fn save_model(model: &DekfModel, path: &Path) -> Result<()> {
    let bytes = slidetrack_estimators::dekf::file::to_bytes(model)?;
    write_atomically(path, &bytes)
}

/// Writes `bytes` to `path` through a temporary file and a rename, so that
/// `path` is either the old file or the complete new one.
pub fn write_atomically(path: &Path, bytes: &[u8]) -> Result<()> {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => std::path::PathBuf::from("."),
    };
    std::fs::create_dir_all(&dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let tmp = dir.join(format!(
        ".{}.tmp-{}",
        path.file_name().map_or("out".into(), |n| n.to_string_lossy()),
        std::process::id()
    ));
    std::fs::write(&tmp, bytes).with_context(|| format!("cannot write {}", tmp.display()))?;
    std::fs::rename(&tmp, path).with_context(|| {
        let _ = std::fs::remove_file(&tmp);
        format!("cannot write {}", path.display())
    })
}
