//! `slidetrack demo`: the whole pipeline on the simulated rig. Collect
//! controlled-sliding trials of the box (camera included), label them with
//! the ArUco ground truth, train a dEKF on the `xy` tactile channels, and
//! evaluate it on held-out sessions: the table of Table 6.1 and the plots
//! of Figs. 6.4-6.9.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Result, bail};
use slidetrack_experiment::dataset::{ChannelSet, TruthSource, load};
use slidetrack_experiment::dekf_eval::{evaluate, table};
use slidetrack_experiment::dekf_run::{save_model, write_atomically};
use slidetrack_experiment::dekf_train::{TrainSpec, Trained};
use slidetrack_experiment::linear_baseline::{LinearBaseline, path_for};
use slidetrack_experiment::pipeline::{DataSpec, collect, label, threads};
use slidetrack_experiment::plot::dekf::plot_training_curve;
use slidetrack_experiment::protocol::Protocol;

use super::train::fit_with_progress;
use crate::cli::{DemoArgs, PlotArgs, PlotKind, ReplayArgs};

pub fn run(args: &DemoArgs, quiet: bool) -> Result<()> {
    if args.train == 0 || args.test == 0 {
        bail!("--train and --test must each be at least 1");
    }
    let started = Instant::now();
    let workers = threads(args.threads);
    let stop = super::stop_flag(super::RELEASING);
    let sessions = args.out.join("sessions");
    let n = args.train + args.test;
    println!(
        "slidetrack demo: {n} controlled-sliding trials of the box on the simulated rig ({} s of cycles each, {workers} at a time)",
        args.duration
    );
    let spec = DataSpec {
        object: "box".into(),
        seed: args.seed,
        trials: 0..n,
        duration_s: args.duration,
        camera: true,
    };
    let files = collect(&spec, &sessions, workers, &stop, &|path, report| match report {
        Some(r) => println!("  {}", r.summary_line()),
        None => println!("  {}: kept from an earlier run", path.display()),
    })?;
    let step = |what: &str| println!("\n[{:5.1} s] {what}", started.elapsed().as_secs_f64());

    step("labelling: marker positions -> Kalman filter + RTS smoother -> /ground_truth/sliding");
    label(&files, Protocol::Default, workers, &stop)?;
    let (train, test) = files.split_at(args.train as usize);

    step(&format!("training the dEKF on {} sessions (xy channels, tactile derivative)", train.len()));
    let model_path = args.out.join("box-xy.safetensors");
    let (trained, linear) = train_step(args, train, &model_path, workers, quiet)?;

    step(&format!("evaluating on {} held-out sessions", test.len()));
    evaluate_step(args, &trained, test, &linear)?;

    step("plots");
    plots(args, &test[0], model_path)?;
    println!("{}", args.out.join("training-curve.png").display());
    println!("\ndone in {:.0} s; everything is in {}", started.elapsed().as_secs_f64(), args.out.display());
    println!(
        "next: `slidetrack track --model {} --vision roft` runs the trackers live; `slidetrack study --quick` the thesis's tables",
        args.out.join("box-xy.safetensors").display()
    );
    Ok(())
}

/// The dEKF trained on `train` and saved at `model_path`, the linear-map
/// baseline fitted beside it, and the training curve plotted.
fn train_step(
    args: &DemoArgs,
    train: &[PathBuf],
    model_path: &Path,
    workers: usize,
    quiet: bool,
) -> Result<(Trained, LinearBaseline)> {
    let spec = TrainSpec {
        channels: ChannelSet::Xy.names(),
        seed: args.seed,
        threads: workers,
        truth: TruthSource::GroundTruth,
        ..TrainSpec::default()
    };
    let sessions = train.iter().map(|f| load(f, Some(spec.truth))).collect::<Result<Vec<_>>>()?;
    let trained = fit_with_progress(&spec, &sessions, quiet)?;
    save_model(&trained.model, model_path)?;
    println!("  {} ({:.1} s of training)", model_path.display(), trained.seconds);
    let linear = LinearBaseline::fit(&trained.model, &sessions)?;
    linear.save(&path_for(model_path))?;
    println!("  {} (the linear-map baseline on the same sessions)", path_for(model_path).display());
    plot_training_curve(&trained.epochs, &args.out.join("training-curve.png"))?;
    Ok((trained, linear))
}

/// The table of `model` on the held-out sessions `test`, against the
/// baselines, written to `eval.json` too.
fn evaluate_step(
    args: &DemoArgs,
    trained: &Trained,
    test: &[PathBuf],
    linear: &LinearBaseline,
) -> Result<()> {
    let report = evaluate(&trained.model, test, TruthSource::GroundTruth, Some(linear))?;
    print!("{}", table(&report));
    let ratio = report.mean.position_rmse_cm / report.mean.baseline_position_rmse_cm.max(1e-12);
    println!(
        "position RMSE {:.3} cm = {:.0} % of the zero-motion baseline's {:.3} cm",
        report.mean.position_rmse_cm,
        ratio * 100.0,
        report.mean.baseline_position_rmse_cm
    );
    if let Some(l) = report.mean.linear_position_rmse_cm {
        println!(
            "the linear map on the same channels: {l:.3} cm ({:.0} % of zero motion); the dEKF is {:.0} % of it",
            100.0 * l / report.mean.baseline_position_rmse_cm.max(1e-12),
            100.0 * report.mean.position_rmse_cm / l.max(1e-12)
        );
    }
    write_atomically(&args.out.join("eval.json"), serde_json::to_string_pretty(&report)?.as_bytes())?;
    Ok(())
}

/// The replay of the first held-out session and the plots of Figs. 6.4, 6.5, 6.8 and 6.9.
fn plots(args: &DemoArgs, first_test: &std::path::Path, model_path: std::path::PathBuf) -> Result<()> {
    super::replay::run_cmd(&ReplayArgs {
        file: first_test.to_path_buf(),
        model: Some(model_path),
        out: args.out.join("replay.mcap"),
        plot: Some(args.out.join("replay.png")),
        overwrite: true,
    })?;
    for (kind, name) in [
        (PlotKind::Overview, "overview.png"),
        (PlotKind::Grasp, "grasp.png"),
        (PlotKind::GroundTruth, "ground-truth.png"),
    ] {
        let out = args.out.join(name);
        super::plot::run(&PlotArgs { file: first_test.to_path_buf(), out, what: kind, recover: false })?;
    }
    Ok(())
}
