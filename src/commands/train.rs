//! `slidetrack train`: fit a dEKF model to labelled sessions.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use rand::SeedableRng;
use serde_json::json;
use slidetrack_estimators::dekf::{
    DekfModel, EpochReport, Measurement, ModelMeta, Selection, Stage, TrainConfig, train_with_selection,
};
use slidetrack_estimators::derivative::DerivativeFilterConfig;

use crate::dataset::{ChannelSet, SessionData, TruthSource, expand, load};
use crate::dekf_run::{Inputs, inputs, normalisation, save_model, sequence};

/// What the feature network reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum MeasurementArg {
    /// The derivative of the tactile signal (the thesis's choice).
    Derivative,
    /// The plain baseline-subtracted signal (ablation of Table 6.3).
    Raw,
}

impl From<MeasurementArg> for Measurement {
    fn from(m: MeasurementArg) -> Measurement {
        match m {
            MeasurementArg::Derivative => Measurement::Derivative,
            MeasurementArg::Raw => Measurement::Raw,
        }
    }
}

/// Arguments of `train`.
#[derive(Debug, Args, Clone)]
pub struct TrainArgs {
    /// Labelled session files, or directories of them.
    #[arg(required = true)]
    pub sessions: Vec<PathBuf>,
    /// Tactile channels the model reads.
    #[arg(long, value_enum, default_value_t = ChannelSet::Xy)]
    pub channels: ChannelSet,
    /// What the model reads: the derivative of the signal or the signal.
    #[arg(long, value_enum, default_value_t = MeasurementArg::Derivative)]
    pub measurement: MeasurementArg,
    /// Model file to write (.safetensors).
    #[arg(long)]
    pub out: PathBuf,
    /// Filter rate (Hz): the tactile stream is decimated to about this rate
    /// (the thesis trained at 30 Hz).
    #[arg(long, default_value_t = 30.0)]
    pub rate_hz: f64,
    /// Schedule as `length:epochs,...` (Sec. 6.2.4: 2:5,4:5,8:5,16:5,32:5).
    #[arg(long, default_value = "2:5,4:5,8:5,16:5,32:5")]
    pub schedule: String,
    /// Subsequences per batch.
    #[arg(long, default_value_t = 32)]
    pub batch: usize,
    /// Adam's learning rate.
    #[arg(long, default_value_t = 1e-3)]
    pub lr: f64,
    /// Seed of initialisation, shuffling and initial-state draws.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Shift each training window by a random offset along the sliding axis,
    /// uniform in +-this (cm), so that the networks cannot tie their output to
    /// where the object happens to be (see the README); 0 keeps the recorded
    /// positions, as the thesis did.
    #[arg(long, default_value_t = DEFAULT_POSITION_SHIFT_CM)]
    pub position_shift: f64,
    /// Keep the parameters of the last epoch instead of those of the epoch
    /// whose filter, run over whole training sessions, tracked the position best
    /// (checked after each epoch of the second half of the schedule).
    #[arg(long)]
    pub no_select: bool,
    /// Worker threads (0: all cores).
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    /// Truth to train against: the ArUco ground truth or the simulator's.
    #[arg(long, value_enum, default_value_t = TruthSource::GroundTruth)]
    pub truth: TruthSource,
    /// Also plot the training curve (state RMSE per epoch, Fig. 6.6).
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// Print a JSON summary instead of text.
    #[arg(long)]
    pub json: bool,
}

/// Default `--position-shift` (cm): without it the position drifts on long
/// sessions (held-out box sessions: 35 % of the zero-motion baseline's RMSE
/// instead of 16 %).
pub const DEFAULT_POSITION_SHIFT_CM: f64 = 20.0;

/// Training sessions the epoch selection runs whole.
const SELECTION_SESSIONS: usize = 8;

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

/// A trained model and how training went.
pub struct Trained {
    /// The model.
    pub model: DekfModel,
    /// One report per epoch.
    pub epochs: Vec<EpochReport>,
    /// Wall time of the optimisation (s).
    pub seconds: f64,
}

/// Trains a model on `args.sessions` (shared by `train`, `study` and `demo`).
pub fn fit(args: &TrainArgs, quiet: bool) -> Result<Trained> {
    let files = expand(&args.sessions)?;
    let sessions = files.iter().map(|f| load(f, Some(args.truth))).collect::<Result<Vec<_>>>()?;
    fit_sessions(args, &sessions, quiet)
}

/// Trains a model on sessions already loaded with their truth (`args.sessions`
/// is not read; the files recorded in the model are the sessions' paths).
pub fn fit_sessions(args: &TrainArgs, sessions: &[SessionData], quiet: bool) -> Result<Trained> {
    if !(args.rate_hz.is_finite() && args.rate_hz > 0.0) {
        bail!("--rate-hz must be positive");
    }
    let schedule = parse_schedule(&args.schedule)?;
    let Some(first) = sessions.first() else { bail!("no sessions to train on") };
    let files: Vec<&Path> = sessions.iter().map(|s| s.path.as_path()).collect();
    let tactile_rate = first.rate_hz;
    for s in sessions {
        if (s.rate_hz - tactile_rate).abs() > 0.05 * tactile_rate {
            bail!(
                "{}: tactile rate {:.1} Hz differs from {:.1} Hz of {}",
                s.path.display(),
                s.rate_hz,
                tactile_rate,
                files[0].display()
            );
        }
    }
    let decimation = ((tactile_rate / args.rate_hz).round() as usize).max(1);
    let dt_s = decimation as f64 / tactile_rate;
    let channels = args.channels.names();
    let measurement = Measurement::from(args.measurement);
    let filter = DerivativeFilterConfig::default();
    let prepared: Vec<Inputs> = sessions
        .iter()
        .map(|s| inputs(s, &channels, measurement, filter, decimation))
        .collect::<Result<_>>()?;
    let cfg = TrainConfig {
        schedule,
        batch_size: args.batch.max(1),
        learning_rate: args.lr,
        seed: args.seed,
        threads: args.threads,
        position_shift_cm: args.position_shift,
        ..TrainConfig::default()
    };
    let meta = ModelMeta {
        dt_s,
        decimation,
        tactile_rate_hz: tactile_rate,
        channels: channels.clone(),
        measurement,
        derivative_filter: filter,
        state_units: ["cm".into(), "cm/s".into()],
        p0_diag: [0.1, 0.1],
        training: json!({
            "config": cfg,
            "truth": args.truth.topic(),
            "channel_set": args.channels.name(),
            "sessions": files.iter().map(|f| f.display().to_string()).collect::<Vec<_>>(),
            "steps": prepared.iter().map(|p| p.times.len()).sum::<usize>(),
        }),
        software_version: env!("CARGO_PKG_VERSION").into(),
    };
    let mut model = DekfModel::new(meta, &mut rand_chacha::ChaCha8Rng::seed_from_u64(args.seed));
    let (mean, std) = normalisation(&prepared.iter().collect::<Vec<_>>(), channels.len());
    model.set_input_normalisation(&mean, &std);
    let data = prepared.iter().map(|p| sequence(&model, p)).collect::<Result<Vec<_>>>()?;

    let bar = if quiet { ProgressBar::hidden() } else { ProgressBar::new(1) };
    bar.set_style(
        ProgressStyle::with_template(
            "training [{bar:30}] {pos}/{len} batches, {elapsed} elapsed, eta {eta}  {msg}",
        )
        .unwrap_or_else(|_| ProgressStyle::default_bar())
        .progress_chars("=> "),
    );
    let started = std::time::Instant::now();
    // Up to 8 training sessions, evenly spaced, run whole from their start.
    let stride = sessions.len().div_ceil(SELECTION_SESSIONS).max(1);
    let chosen: Vec<&SessionData> = sessions.iter().step_by(stride).collect();
    let mut score = |m: &DekfModel| -> f64 {
        let rmse: Result<Vec<f64>> =
            chosen.iter().map(|d| Ok(super::eval::score_session(m, d)?.position_rmse_cm)).collect();
        rmse.map_or(f64::NAN, |v| v.iter().sum::<f64>() / v.len().max(1) as f64)
    };
    let select: Option<Selection> = (!args.no_select)
        .then_some((cfg.schedule.len() / 2, &mut score as &mut dyn FnMut(&DekfModel) -> f64));
    let epochs = train_with_selection(
        &mut model,
        &data,
        &cfg,
        &mut |p| {
            bar.set_length(p.overall.1 as u64);
            bar.set_position(p.overall.0 as u64);
            if p.batch.0 == p.batch.1 || p.overall.0 % 10 == 0 {
                bar.set_message(format!(
                    "length {} epoch {}: RMSE {:.3} cm, {:.3} cm/s",
                    p.length,
                    p.epoch + 1,
                    p.rmse[0],
                    p.rmse[1]
                ));
            }
        },
        select,
    );
    bar.finish_and_clear();
    let seconds = started.elapsed().as_secs_f64();
    if let Some(training) = model.meta.training.as_object_mut() {
        training.insert("epochs".into(), json!(epochs));
        training.insert("seconds".into(), json!(seconds));
    }
    Ok(Trained { model, epochs, seconds })
}

pub fn run(args: &TrainArgs, quiet: bool) -> Result<()> {
    let trained = fit(args, quiet)?;
    save_model(&trained.model, &args.out)?;
    if let Some(plot) = &args.plot {
        plot_training_curve(&trained.epochs, plot)?;
    }
    let last = trained.epochs.last();
    if args.json {
        let out = json!({
            "model": args.out,
            "channels": trained.model.meta.channels,
            "measurement": trained.model.meta.measurement.name(),
            "dt_s": trained.model.meta.dt_s,
            "seconds": trained.seconds,
            "epochs": trained.epochs,
        });
        println!("{}", serde_json::to_string_pretty(&out)?);
    } else {
        println!(
            "{}: {} channels ({}), {} epochs in {:.1} s; final training RMSE {:.3} cm, {:.3} cm/s",
            args.out.display(),
            trained.model.meta.channels.len(),
            trained.model.meta.measurement.name(),
            trained.epochs.len(),
            trained.seconds,
            last.map_or(f64::NAN, |e| e.rmse[0]),
            last.map_or(f64::NAN, |e| e.rmse[1]),
        );
        let best = trained
            .epochs
            .iter()
            .filter_map(|e| e.selection_score.map(|s| (e.epoch, s)))
            .min_by(|a, b| a.1.total_cmp(&b.1));
        if let Some((epoch, score)) = best {
            println!(
                "  kept epoch {epoch}: position RMSE {score:.3} cm over whole training sessions (--no-select keeps the last)"
            );
        }
    }
    Ok(())
}

/// State RMSE per epoch (Fig. 6.6).
pub fn plot_training_curve(epochs: &[EpochReport], out: &Path) -> Result<()> {
    use crate::plot::{PALETTE, Panel, Series, draw_stacked_x};
    let pos: Vec<(f64, f64)> = epochs.iter().map(|e| (e.epoch as f64, e.rmse[0])).collect();
    let vel: Vec<(f64, f64)> = epochs.iter().map(|e| (e.epoch as f64, e.rmse[1])).collect();
    let whole: Vec<(f64, f64)> =
        epochs.iter().filter_map(|e| e.selection_score.map(|s| (e.epoch as f64, s))).collect();
    let mut position = vec![Series::line("training windows", PALETTE[0], pos)];
    if !whole.is_empty() {
        position.push(Series::line("whole training sessions (epoch selection)", PALETTE[3], whole));
    }
    let panels = [
        Panel { title: "position RMSE on the training data".into(), y_label: "cm".into(), series: position },
        Panel {
            title: "velocity RMSE on the training data".into(),
            y_label: "cm/s".into(),
            series: vec![Series::line("velocity", PALETTE[1], vel)],
        },
    ];
    draw_stacked_x(out, "dEKF training", "epoch", &panels)
}
