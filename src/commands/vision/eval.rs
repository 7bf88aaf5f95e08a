//! `slidetrack vision eval`: the trackers scored against ground truth.

use anyhow::{Context, Result};
use indicatif::{ProgressBar, ProgressStyle};
use serde::Serialize;
use slidetrack_estimators::metrics::{SequenceMetrics, perturbed_start};
use slidetrack_experiment::vision_sim::{evaluate_variant, maskukf_on_sequence};
use slidetrack_sim::rgbd::{FastSequenceConfig, SimObjectKind};
use slidetrack_vision::eval::{Scored, Variant, errors, track};
use slidetrack_vision::sources::SlowNetworkConfig;
use slidetrack_vision::{TrackerSettings, build_tracker};

use super::inputs::{InputOptions, Prepared, prepare};
use crate::cli::VisionEvalArgs as EvalArgs;

/// One row of the results.
#[derive(Debug, Serialize)]
struct Row {
    label: String,
    #[serde(flatten)]
    metrics: SequenceMetrics,
}

pub fn run(args: &EvalArgs, quiet: bool) -> Result<()> {
    let rows = if args.input.is_empty() { simulated(args, quiet)? } else { inputs(args)? };
    if args.json {
        println!("{}", serde_json::to_string_pretty(&rows)?);
    } else {
        print_table(&rows);
    }
    Ok(())
}

/// The simulated fast sequences of `args`.
fn sequences(args: &EvalArgs) -> Result<Vec<FastSequenceConfig>> {
    let kinds: Vec<SimObjectKind> = if args.objects.is_empty() {
        SimObjectKind::ALL.to_vec()
    } else {
        args.objects
            .iter()
            .map(|o| SimObjectKind::from_name(o).with_context(|| format!("unknown object '{o}'")))
            .collect::<Result<_>>()?
    };
    anyhow::ensure!(args.duration >= 1.0, "--duration must be at least 1 s");
    let mut out = Vec::new();
    for (i, kind) in kinds.iter().enumerate() {
        for s in 0..args.sequences.max(1) {
            let seed = args.seed + (i * args.sequences.max(1) + s) as u64;
            out.push(FastSequenceConfig::new(*kind, args.duration, seed));
        }
    }
    Ok(out)
}

fn simulated(args: &EvalArgs, quiet: bool) -> Result<Vec<Row>> {
    let configs = sequences(args)?;
    let network = SlowNetworkConfig::default();
    let settings = TrackerSettings::default();
    let variants: Vec<Variant> =
        if args.ablation { Variant::TABLE_5_6.to_vec() } else { vec![Variant::Roft, Variant::Network] };
    let bar = if quiet { ProgressBar::hidden() } else { ProgressBar::new(variants.len() as u64 + 1) };
    bar.set_style(ProgressStyle::with_template("{bar:40} {pos}/{len} {msg}")?);
    let mut rows = Vec::new();
    for v in variants {
        bar.set_message(v.label());
        let r = evaluate_variant(v, &configs, &network, &settings)?;
        rows.push(Row { label: r.label.to_string(), metrics: r.metrics });
        bar.inc(1);
    }
    // MaskUKF with the true masks of every frame, started 5 cm and 10 degrees
    // off, on the fast sequences and on the same paths at YCB-Video-like
    // speeds (15 cm/s, 45 deg/s), for which its motion model is tuned.
    bar.set_message("MaskUKF");
    for (label, slow) in
        [("MaskUKF (true masks, start 5 cm / 10 deg off)", false), ("MaskUKF (same, YCB-Video speeds)", true)]
    {
        let mut all = Vec::new();
        for c in &configs {
            let mut c = c.clone();
            if slow {
                c.motion.max_speed_mps = c.motion.max_speed_mps.min(0.15);
                c.motion.max_angular_speed_dps = c.motion.max_angular_speed_dps.min(45.0);
            }
            let first = slidetrack_sim::rgbd::FastSequence::new(c.clone())?.truth(0).camera_from_object;
            let (frames, model) = maskukf_on_sequence(&c, perturbed_start(&first), &settings)?;
            all.extend(errors(&frames, 0, Scored::Tracker, &*model.object_points()?));
        }
        rows.push(Row { label: label.into(), metrics: slidetrack_estimators::metrics::summarize(&all) });
    }
    bar.finish_and_clear();
    Ok(rows)
}

fn inputs(args: &EvalArgs) -> Result<Vec<Row>> {
    let model =
        args.model.as_deref().context("--input needs --model (a file, or `sim` for simulated sessions)")?;
    let mut rows = Vec::new();
    let mut all = Vec::new();
    for input in &args.input {
        let options = InputOptions {
            model,
            model_scale: 1.0,
            object: args.object.as_deref(),
            measurements: args.measurements,
            init: args.init,
            recover: false,
            aruco_config: None,
            external: None,
        };
        let Prepared { mut source, mut measurements, model, intrinsics, initial_pose } =
            prepare(input, &options)?;
        let settings = TrackerSettings { initial_pose, ..TrackerSettings::default() };
        let mut tracker = build_tracker(args.tracker.kind(), &model, &intrinsics, &settings)?;
        let frames = track(source.as_mut(), measurements.as_mut(), Some(tracker.as_mut()), |_, _| {})?;
        anyhow::ensure!(!frames.is_empty(), "{}: no frame has a true pose to score against", input.display());
        let first = frames.iter().position(|f| f.estimate.is_some()).unwrap_or(0);
        let e = errors(&frames, first, Scored::Tracker, &*model.object_points()?);
        rows.push(Row {
            label: input.display().to_string(),
            metrics: slidetrack_estimators::metrics::summarize(&e),
        });
        all.extend(e);
    }
    if args.input.len() > 1 {
        rows.push(Row { label: "ALL".into(), metrics: slidetrack_estimators::metrics::summarize(&all) });
    }
    Ok(rows)
}

fn print_table(rows: &[Row]) {
    let width = rows.iter().map(|r| r.label.len()).max().unwrap_or(10).max(10);
    println!(
        "{:width$}  {:>7}  {:>7}  {:>8}  {:>9}  {:>10}  {:>10}",
        "variant", "ADD-AUC", "ADI-AUC", "pos cm", "rot deg", "vel cm/s", "ang deg/s"
    );
    let opt = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.2}"));
    for r in rows {
        let m = &r.metrics;
        println!(
            "{:width$}  {:>7.2}  {:>7.2}  {:>8.2}  {:>9.2}  {:>10}  {:>10}",
            r.label,
            m.add_auc_percent,
            m.adi_auc_percent,
            m.position_rmse_cm,
            m.rotation_rmse_deg,
            opt(m.linear_velocity_rmse_cmps),
            opt(m.angular_velocity_rmse_degps)
        );
    }
    println!("(AUC at 10 cm, RMSE over all scored frames; thesis Sec. 3.4)");
}
