//! `slidetrack vision eval`: the trackers scored against ground truth.

use anyhow::Result;
use indicatif::{ProgressBar, ProgressStyle};
use slidetrack_experiment::vision::eval::{
    EvalStep, InputEvalOptions, ScoreRow, SimulatedEvalOptions, inputs, simulated,
};

use crate::cli::VisionEvalArgs as EvalArgs;

pub fn run(args: &EvalArgs, quiet: bool) -> Result<()> {
    let rows = if args.input.is_empty() {
        simulated_rows(args, quiet)?
    } else {
        inputs(&InputEvalOptions {
            inputs: &args.input,
            kind: args.tracker.kind(),
            model: args.model.as_deref(),
            object: args.object.as_deref(),
            measurements: args.measurements.into(),
            init: args.init.into(),
        })?
    };
    if args.json {
        println!("{}", serde_json::to_string_pretty(&rows)?);
    } else {
        print_table(&rows);
    }
    Ok(())
}

/// The simulated sequences of `args`, scored, with a progress bar.
fn simulated_rows(args: &EvalArgs, quiet: bool) -> Result<Vec<ScoreRow>> {
    let options = SimulatedEvalOptions {
        sequences: args.sequences,
        objects: args.objects.clone(),
        duration_s: args.duration,
        seed: args.seed,
        ablation: args.ablation,
    };
    let mut bar = ProgressBar::hidden();
    let style = ProgressStyle::with_template("{bar:40} {pos}/{len} {msg}")?;
    let rows = simulated(&options, &mut |step| match step {
        EvalStep::Total(n) => {
            bar = if quiet { ProgressBar::hidden() } else { ProgressBar::new(n) };
            bar.set_style(style.clone());
        }
        EvalStep::Start(label) => bar.set_message(label.to_string()),
        EvalStep::Done => bar.inc(1),
    })?;
    bar.finish_and_clear();
    Ok(rows)
}

fn print_table(rows: &[ScoreRow]) {
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
