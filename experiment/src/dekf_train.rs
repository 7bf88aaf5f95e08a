//! Training a dEKF on sessions (thesis Sec. 6.2.4): the model's inputs from
//! each session, the normalisation, BPTT over the schedule and the epoch
//! selection on whole training sessions.

use anyhow::{Context, Result, bail};
use rand::SeedableRng;
use serde_json::json;
use slidetrack_estimators::dekf::{
    Architecture, Batching, DEFAULT_PART_WINDOWS, DekfModel, EpochReport, Measurement, ModelMeta, Progress,
    Selection, Sequence, Stage, StateKind, TrainConfig, train_with_selection,
};
use slidetrack_estimators::derivative::{DEFAULT_OUTLIER_GATE_SIGMA, DerivativeFilterConfig};

use crate::dataset::{ChannelSet, SessionData, TruthSource};
use crate::dekf_eval::score_session;

/// The model options a training takes, for its callers to name.
pub mod model_options {
    pub use slidetrack_estimators::dekf::{
        Activation, Architecture, Batching, DEFAULT_PART_WINDOWS, Measurement, StateKind,
    };
    pub use slidetrack_estimators::derivative::DEFAULT_OUTLIER_GATE_SIGMA;
}
use crate::dekf_run::{DEFAULT_RATE_TOLERANCE, Inputs, RATE_TOLERANCE_KEY, inputs, normalisation, sequence};

/// Default `--position-shift` (cm): without it the position drifts on long
/// sessions (held-out box sessions: 35 % of the zero-motion baseline's RMSE
/// instead of 16 %).
pub const DEFAULT_POSITION_SHIFT_CM: f64 = 20.0;

/// Default `--clip-norm`.
pub const DEFAULT_CLIP_NORM: f64 = 10.0;

/// Training sessions the epoch selection runs whole.
const SELECTION_SESSIONS: usize = 8;

/// What to train: the model's inputs and the optimisation.
#[derive(Clone, Debug, PartialEq)]
pub struct TrainSpec {
    /// Tactile channels the model reads, by name (see [`crate::channels`]).
    pub channels: Vec<String>,
    /// What the feature network reads.
    pub measurement: Measurement,
    /// Filter rate (Hz): the tactile stream is decimated to about this rate.
    pub rate_hz: f64,
    /// Subsequence lengths and epochs (Sec. 6.2.4: 2:5,4:5,8:5,16:5,32:5).
    pub schedule: Vec<Stage>,
    /// Subsequences per batch.
    pub batch: usize,
    /// How the windows are grouped into batches.
    pub batching: Batching,
    /// Adam's learning rate.
    pub learning_rate: f64,
    /// Largest global norm of a batch's gradient (larger ones are scaled
    /// down); `None`: no clipping.
    pub clip_norm: Option<f64>,
    /// Seed of initialisation, shuffling and initial-state draws.
    pub seed: u64,
    /// Random shift of each window along the sliding axis, uniform in +- this (cm).
    pub position_shift_cm: f64,
    /// Normalise each input channel by its mean and standard deviation over
    /// the training data (stored in the model); otherwise mean 0, std 1.
    pub normalise_inputs: bool,
    /// Keep the epoch whose filter tracks whole training sessions best
    /// (second half of the schedule); otherwise the last epoch.
    pub select_epoch: bool,
    /// Worker threads (0: all cores). The model does not depend on them.
    pub threads: usize,
    /// Windows per part of a batch's gradient: a batch keeps up to
    /// `batch / part_windows` threads busy; the model depends on it by
    /// float rounding (it is written to the model's training config).
    pub part_windows: usize,
    /// The truth trained against.
    pub truth: TruthSource,
    /// Largest relative difference of a session's tactile rate from the
    /// model's (the first session's), here and when the model runs
    /// ([`crate::dekf_run::rate_tolerance`]); 0.05 unless a dataset's rates
    /// vary more (imported recordings on a mean-rate clock).
    pub rate_tolerance: f64,
    /// Gate of the derivative filter against isolated tactile spikes
    /// (standard deviations; 0: off), stored in the model so that it runs
    /// as it was trained.
    pub outlier_gate_sigma: f64,
    /// Width, residual blocks and activation of the networks (default: the
    /// thesis's 64, 3, ReLU).
    pub architecture: Architecture,
    /// The state tracked: the thesis's sliding (default) or planar slip
    /// (trained against `/ground_truth/planar`, whatever `truth` says).
    pub state: StateKind,
}

impl Default for TrainSpec {
    /// The thesis's protocol plus this project's defaults (xy derivative
    /// channels at 30 Hz, position shift, epoch selection), ground truth.
    fn default() -> Self {
        TrainSpec {
            channels: ChannelSet::Xy.names(),
            measurement: Measurement::Derivative,
            rate_hz: 30.0,
            schedule: [2, 4, 8, 16, 32].map(|length| Stage { length, epochs: 5 }).to_vec(),
            batch: 32,
            batching: Batching::Windows,
            learning_rate: 1e-3,
            clip_norm: Some(DEFAULT_CLIP_NORM),
            seed: 1,
            position_shift_cm: DEFAULT_POSITION_SHIFT_CM,
            normalise_inputs: true,
            select_epoch: true,
            threads: 0,
            part_windows: DEFAULT_PART_WINDOWS,
            truth: TruthSource::GroundTruth,
            rate_tolerance: DEFAULT_RATE_TOLERANCE,
            outlier_gate_sigma: DEFAULT_OUTLIER_GATE_SIGMA,
            architecture: Architecture::default(),
            state: StateKind::Sliding,
        }
    }
}

/// Parses `2:5,4:5` into stages.
pub fn parse_schedule(s: &str) -> Result<Vec<Stage>> {
    let stages: Result<Vec<Stage>> = s
        .split(',')
        .map(|part| {
            let (l, e) = part
                .trim()
                .split_once(':')
                .with_context(|| format!("schedule stage `{part}` is not length:epochs"))?;
            let length: usize = l.parse().with_context(|| format!("bad length in `{part}`"))?;
            let epochs: usize = e.parse().with_context(|| format!("bad epoch count in `{part}`"))?;
            if length == 0 {
                bail!("schedule stage `{part}`: length must be at least 1");
            }
            Ok(Stage { length, epochs })
        })
        .collect();
    let stages = stages.context("invalid --schedule")?;
    if stages.is_empty() {
        bail!("invalid --schedule: no stages");
    }
    Ok(stages)
}

/// The epoch selection's score of `model` on one whole session: the RMSE of
/// the position components of the state (in the model's units: cm for
/// sliding; mm, mm and deg for planar), from the session's first scan.
fn selection_score(model: &DekfModel, data: &SessionData) -> Result<f64> {
    match model.state() {
        StateKind::Sliding => Ok(score_session(model, data)?.position_rmse_cm),
        StateKind::Planar => {
            let m = &model.meta;
            let truth = inputs(data, &m.channels, m.measurement, m.derivative_filter, m.decimation)?;
            let outputs = crate::dekf_run::run(model, data)?;
            let (mut sq, mut n) = (0.0, 0usize);
            for (k, (_, o)) in outputs.iter().enumerate() {
                let Some(x) = truth.truth_at(k) else { break };
                if x.iter().all(|v| v.is_finite()) {
                    sq += (0..3).map(|i| (o.mean[i] - x[i]).powi(2)).sum::<f64>();
                    n += 1;
                }
            }
            Ok((sq / n.max(1) as f64).sqrt())
        }
    }
}

/// A trained model and how training went.
pub struct Trained {
    /// The model.
    pub model: DekfModel,
    /// One report per epoch.
    pub epochs: Vec<EpochReport>,
    /// Wall time of the optimisation (s).
    pub seconds: f64,
}

/// The tactile rate shared by `sessions` (Hz), the first one's; fails when
/// one differs from it by more than `tolerance` (relative).
fn common_tactile_rate(sessions: &[SessionData], tolerance: f64) -> Result<f64> {
    let Some(first) = sessions.first() else { bail!("no sessions to train on") };
    for s in sessions {
        if (s.rate_hz - first.rate_hz).abs() > tolerance * first.rate_hz {
            bail!(
                "{}: tactile rate {:.1} Hz differs from {:.1} Hz of {} by more than {:.0} % (--rate-tolerance)",
                s.path.display(),
                s.rate_hz,
                first.rate_hz,
                first.path.display(),
                tolerance * 100.0
            );
        }
    }
    Ok(first.rate_hz)
}

/// A new model for `spec` on `sessions`, its input normalisation set, and
/// its training sequences.
fn new_model(
    spec: &TrainSpec,
    cfg: &TrainConfig,
    sessions: &[SessionData],
) -> Result<(DekfModel, Vec<Sequence>)> {
    let tactile_rate = common_tactile_rate(sessions, spec.rate_tolerance)?;
    let decimation = ((tactile_rate / spec.rate_hz).round() as usize).max(1);
    let channels = spec.channels.clone();
    let filter = DerivativeFilterConfig { outlier_gate_sigma: spec.outlier_gate_sigma, ..Default::default() };
    let prepared: Vec<Inputs> = sessions
        .iter()
        .map(|s| inputs(s, &channels, spec.measurement, filter, decimation))
        .collect::<Result<_>>()?;
    let files: Vec<String> = sessions.iter().map(|s| s.path.display().to_string()).collect();
    let mut meta = ModelMeta {
        dt_s: decimation as f64 / tactile_rate,
        decimation,
        tactile_rate_hz: tactile_rate,
        channels: channels.clone(),
        measurement: spec.measurement,
        derivative_filter: filter,
        state: spec.state,
        state_units: spec.state.units(),
        p0_diag: spec.state.default_p0_diag(),
        training: json!({
            "config": cfg,
            "truth": spec.truth.for_state(spec.state).topic(),
            "channel_set": ChannelSet::named(&spec.channels).map_or("custom", ChannelSet::name),
            "sessions": files,
            "steps": prepared.iter().map(|p| p.times.len()).sum::<usize>(),
        }),
        software_version: env!("CARGO_PKG_VERSION").into(),
    };
    if spec.rate_tolerance != DEFAULT_RATE_TOLERANCE
        && let Some(training) = meta.training.as_object_mut()
    {
        training.insert(RATE_TOLERANCE_KEY.into(), json!(spec.rate_tolerance));
    }
    let mut model = DekfModel::with_architecture(
        meta,
        &spec.architecture,
        &mut rand_chacha::ChaCha8Rng::seed_from_u64(spec.seed),
    );
    if spec.normalise_inputs {
        let (mean, std) = normalisation(&prepared.iter().collect::<Vec<_>>(), channels.len());
        model.set_input_normalisation(&mean, &std);
    }
    let data = prepared.iter().map(|p| sequence(&model, p)).collect::<Result<Vec<_>>>()?;
    Ok((model, data))
}

/// Trains a model on sessions loaded with their truth; `progress` sees every
/// batch. The sessions' paths are recorded in the model's training metadata.
pub fn fit_sessions(
    spec: &TrainSpec,
    sessions: &[SessionData],
    progress: &mut dyn FnMut(&Progress),
) -> Result<Trained> {
    if !(spec.rate_hz.is_finite() && spec.rate_hz > 0.0) {
        bail!("the filter rate must be positive, got {} Hz", spec.rate_hz);
    }
    if spec.schedule.is_empty() {
        bail!("the training schedule has no stages");
    }
    if let Some(problem) = spec.architecture.problem() {
        bail!("invalid network architecture: {problem}");
    }
    if spec.part_windows == 0 {
        bail!("the windows per part of a batch's gradient (--part-windows) must be at least 1");
    }
    if !(spec.rate_tolerance.is_finite() && spec.rate_tolerance >= 0.0) {
        bail!("the rate tolerance must be a non-negative fraction, got {}", spec.rate_tolerance);
    }
    let cfg = TrainConfig {
        schedule: spec.schedule.clone(),
        batch_size: spec.batch.max(1),
        batching: spec.batching,
        learning_rate: spec.learning_rate,
        clip_norm: spec.clip_norm,
        seed: spec.seed,
        threads: spec.threads,
        part_windows: spec.part_windows,
        position_shift_cm: spec.position_shift_cm,
        ..TrainConfig::default()
    };
    let (mut model, data) = new_model(spec, &cfg, sessions)?;
    let started = std::time::Instant::now();
    // Up to 8 training sessions, evenly spaced, run whole from their start.
    let stride = sessions.len().div_ceil(SELECTION_SESSIONS).max(1);
    let chosen: Vec<&SessionData> = sessions.iter().step_by(stride).collect();
    let mut score = |m: &DekfModel| -> f64 {
        let rmse: Result<Vec<f64>> = chosen.iter().map(|d| selection_score(m, d)).collect();
        rmse.map_or(f64::NAN, |v| v.iter().sum::<f64>() / v.len().max(1) as f64)
    };
    let select: Option<Selection> = spec
        .select_epoch
        .then_some((cfg.schedule.len() / 2, &mut score as &mut dyn FnMut(&DekfModel) -> f64));
    let epochs = train_with_selection(&mut model, &data, &cfg, progress, select);
    let seconds = started.elapsed().as_secs_f64();
    // No wall time in the file: the same seed and data give the same bytes.
    if let Some(training) = model.meta.training.as_object_mut() {
        training.insert("epochs".into(), json!(epochs));
    }
    Ok(Trained { model, epochs, seconds })
}
