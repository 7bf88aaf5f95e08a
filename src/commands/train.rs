//! `slidetrack train`: fit a dEKF model to labelled sessions.

use anyhow::Result;
use indicatif::{ProgressBar, ProgressStyle};
use serde_json::json;
use slidetrack_experiment::dataset::{
    ChannelSet, MIN_SCANS, SessionData, TruthSource, expand, load, load_unless_short,
};
use slidetrack_experiment::dekf_run::save_model;
use slidetrack_experiment::dekf_train::model_options::{Architecture, StateKind};
use slidetrack_experiment::dekf_train::{TrainSpec, Trained, fit_sessions, parse_schedule};
use slidetrack_experiment::linear_baseline::{LinearBaseline, path_for};
use slidetrack_experiment::plot::dekf::plot_training_curve;
use slidetrack_experiment::protocol::Protocol;

use crate::cli::TrainArgs;

/// The training `args` ask for.
pub fn spec(args: &TrainArgs) -> Result<TrainSpec> {
    let protocol: Option<Protocol> = args.protocol.map(Into::into);
    let truth = match (args.truth, protocol) {
        (Some(truth), _) => truth.into(),
        (None, Some(p)) => p.truth(),
        (None, None) => TruthSource::GroundTruth,
    };
    let spec = TrainSpec {
        channels: ChannelSet::parse_channels(&args.channels),
        measurement: args.measurement.into(),
        rate_hz: args.rate_hz,
        schedule: parse_schedule(&args.schedule)?,
        batch: args.batch,
        batching: args.batching.into(),
        learning_rate: args.lr,
        clip_norm: (args.clip_norm > 0.0).then_some(args.clip_norm),
        seed: args.seed,
        position_shift_cm: args.position_shift,
        select_epoch: !args.no_select,
        normalise_inputs: !args.no_normalise,
        threads: args.threads,
        part_windows: args.part_windows,
        truth,
        rate_tolerance: args.rate_tolerance,
        outlier_gate_sigma: args.outlier_gate,
        architecture: Architecture {
            width: args.width,
            residual_blocks: args.blocks,
            activation: args.activation.into(),
        },
        state: args.state.into(),
    };
    Ok(match protocol {
        Some(p) => p.training(spec),
        None => spec,
    })
}

/// Trains `spec` on `sessions` with a progress bar (hidden when `quiet`).
pub fn fit_with_progress(spec: &TrainSpec, sessions: &[SessionData], quiet: bool) -> Result<Trained> {
    let bar = if quiet { ProgressBar::hidden() } else { ProgressBar::new(1) };
    bar.set_style(
        ProgressStyle::with_template(
            "training [{bar:30}] {pos}/{len} batches, {elapsed} elapsed, eta {eta}  {msg}",
        )
        .unwrap_or_else(|_| ProgressStyle::default_bar())
        .progress_chars("=> "),
    );
    let trained = fit_sessions(spec, sessions, &mut |p| {
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
    });
    bar.finish_and_clear();
    trained
}

/// Reads the sessions of `args` with their truth, trains on them, and fits
/// the linear-map baseline on the same sessions (unless `--no-linear`).
pub fn fit(args: &TrainArgs, quiet: bool) -> Result<(Trained, Option<LinearBaseline>)> {
    let spec = spec(args)?;
    let files = expand(&args.sessions)?;
    let truth = spec.truth.for_state(spec.state);
    let sessions = if truth == TruthSource::Planar {
        // A grasp lost at once leaves a hold too short to train on.
        let mut kept = Vec::new();
        for f in &files {
            match load_unless_short(f, Some(truth))? {
                Some(d) => kept.push(d),
                None => eprintln!(
                    "warning: {}: skipped, fewer than {MIN_SCANS} tactile scans in the hold",
                    f.display()
                ),
            }
        }
        kept
    } else {
        files.iter().map(|f| load(f, Some(truth))).collect::<Result<Vec<_>>>()?
    };
    let trained = fit_with_progress(&spec, &sessions, quiet)?;
    let linear = (!args.no_linear).then(|| LinearBaseline::fit(&trained.model, &sessions)).transpose()?;
    Ok((trained, linear))
}

pub fn run(args: &TrainArgs, quiet: bool) -> Result<()> {
    let (trained, linear) = fit(args, quiet)?;
    save_model(&trained.model, &args.out)?;
    if let Some(linear) = &linear {
        linear.save(&path_for(&args.out))?;
    }
    if let Some(plot) = &args.plot {
        plot_training_curve(&trained.epochs, plot)?;
    }
    let last = trained.epochs.last();
    if args.json {
        let out = json!({
            "model": args.out,
            "linear": linear.as_ref().map(|_| path_for(&args.out)),
            "state": trained.model.state(),
            "channels": trained.model.meta.channels,
            "architecture": trained.model.architecture(),
            "measurement": trained.model.meta.measurement.name(),
            "dt_s": trained.model.meta.dt_s,
            "seconds": trained.seconds,
            "epochs": trained.epochs,
        });
        println!("{}", serde_json::to_string_pretty(&out)?);
    } else {
        let units = trained.model.state().units();
        let (p, v) = units.split_at(trained.model.state().dofs());
        println!(
            "{}: {} state, {} channels ({}), {} epochs in {:.1} s; final training RMSE {:.3} {}, {:.3} {}",
            args.out.display(),
            trained.model.state(),
            trained.model.meta.channels.len(),
            trained.model.meta.measurement.name(),
            trained.epochs.len(),
            trained.seconds,
            last.map_or(f64::NAN, |e| e.rmse[0]),
            p.join("|"),
            last.map_or(f64::NAN, |e| e.rmse[1]),
            v.join("|"),
        );
        if linear.is_some() {
            println!("  linear-map baseline: {}", path_for(&args.out).display());
        }
        let best = trained
            .epochs
            .iter()
            .filter_map(|e| e.selection_score.map(|s| (e.epoch, s)))
            .min_by(|a, b| a.1.total_cmp(&b.1));
        if let Some((epoch, score)) = best {
            let unit = if trained.model.state() == StateKind::Planar { "mm|deg" } else { "cm" };
            println!(
                "  kept epoch {epoch}: position RMSE {score:.3} {unit} over whole training sessions (--no-select keeps the last)"
            );
        }
    }
    Ok(())
}
