//! `slidetrack calibrate tactile`: fit a tactile force calibration and
//! print its errors beside the trivial maps', or apply one to a session.

use anyhow::{Context, Result};
use serde_json::json;
use slidetrack_experiment::tactile_force::ForceModelKind;
use slidetrack_experiment::tactile_force::apply::{TactileApplyOptions, apply_tactile_calibration};
use slidetrack_experiment::tactile_force::fit::{
    TactileFitOptions, TactileFitReport, fit_tactile_calibration,
};

use crate::cli::{CalibrateTactileArgs, ForceModelArg};

pub fn run(args: &CalibrateTactileArgs, quiet: bool) -> Result<()> {
    match &args.apply {
        Some(session) => apply(args, session, quiet),
        None => fit(args, quiet),
    }
}

fn apply(args: &CalibrateTactileArgs, session: &std::path::Path, quiet: bool) -> Result<()> {
    let options = TactileApplyOptions {
        session: session.to_path_buf(),
        calibration: args.calibration.clone().context("--apply needs --calibration")?,
        out: args.out.clone().context("--apply needs --out")?,
        overwrite: args.overwrite,
    };
    let scans = apply_tactile_calibration(&options)?;
    if args.json {
        println!("{}", json!({"out": options.out.display().to_string(), "scans": scans}));
    } else if !quiet {
        println!("{}: /tactile/calibrated on {scans} scans", options.out.display());
    }
    Ok(())
}

fn fit(args: &CalibrateTactileArgs, quiet: bool) -> Result<()> {
    let options = TactileFitOptions {
        fit: args.fit.clone(),
        eval: args.eval.clone(),
        model: match args.model {
            ForceModelArg::Linear => ForceModelKind::Linear,
            ForceModelArg::Quadratic => ForceModelKind::Quadratic,
        },
        out: args.out.clone(),
        overwrite: args.overwrite,
    };
    let report = fit_tactile_calibration(&options)?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&to_json(&report, args))?);
    } else if !quiet {
        print_text(&report, args);
    }
    Ok(())
}

fn print_text(report: &TactileFitReport, args: &CalibrateTactileArgs) {
    let on = if report.held_out { "held-out" } else { "fit (no --eval)" };
    println!(
        "{} model, fitted on {} scans ({} outliers left out); errors on {} {on} scans, RMS per axis x y z:",
        report.calibration.model.name(),
        report.fit_scans,
        report.outliers,
        report.eval_scans
    );
    let range = report.errors.first().map_or([0.0; 3], |m| m.errors.range_n);
    println!("  reference range         {:>9.4} {:>9.4} {:>9.4} N", range[0], range[1], range[2]);
    for m in &report.errors {
        let (e, r) = (m.errors.rms_n, m.errors.rms_of_range());
        println!(
            "  {:<14} RMS {:>9.4} {:>9.4} {:>9.4} N = {:>6.2} {:>6.2} {:>6.2} % of range",
            m.map,
            e[0],
            e[1],
            e[2],
            100.0 * r[0],
            100.0 * r[1],
            100.0 * r[2]
        );
    }
    if let Some(out) = &args.out {
        println!("calibration written to {}", out.display());
    }
}

fn to_json(report: &TactileFitReport, args: &CalibrateTactileArgs) -> serde_json::Value {
    let maps: Vec<_> = report
        .errors
        .iter()
        .map(|m| {
            json!({
                "map": m.map,
                "rms_n": m.errors.rms_n,
                "max_abs_n": m.errors.max_abs_n,
                "range_n": m.errors.range_n,
                "rms_of_range": m.errors.rms_of_range(),
                "samples": m.errors.samples,
            })
        })
        .collect();
    json!({
        "model": report.calibration.model.name(),
        "out": args.out.as_ref().map(|p| p.display().to_string()),
        "fit_scans": report.fit_scans,
        "eval_scans": report.eval_scans,
        "held_out": report.held_out,
        "outliers": report.outliers,
        "maps": maps,
    })
}
