//! `slidetrack vision track --input`: a tracker over a session or a directory.

use anyhow::{Context, Result};
use indicatif::{ProgressBar, ProgressStyle};
use serde_json::json;
use slidetrack_experiment::vision::offline::{OfflineOptions, OfflineSummary, OfflineTracking};

use crate::cli::VisionTrackArgs as TrackArgs;

pub fn run(args: &TrackArgs, quiet: bool) -> Result<()> {
    let input = args.input.as_deref().context("vision track needs --input or --live")?;
    let options = OfflineOptions {
        input,
        input_options: args.input_options(),
        kind: args.tracker.kind(),
        pose_reset: args.pose_reset,
        out: args.out.as_deref(),
        overwrite: args.overwrite,
    };
    let tracking = OfflineTracking::open(&options)?;
    let bar = match (quiet, tracking.len_hint()) {
        (false, Some(n)) => ProgressBar::new(n as u64),
        _ => ProgressBar::hidden(),
    };
    bar.set_style(ProgressStyle::with_template("{bar:40} {pos}/{len} frames {eta}")?);
    let summary = tracking.run(&mut || bar.inc(1))?;
    bar.finish_and_clear();
    report(args, &summary);
    if let Some(measurements) = &summary.measurement_summary {
        eprintln!("{measurements}");
    }
    Ok(())
}

fn report(args: &TrackArgs, summary: &OfflineSummary) {
    let name = args.tracker.kind().name();
    let OfflineSummary { frames, tracked, tracker_fps: fps, .. } = *summary;
    if args.json {
        let out = json!({
            "tracker": name,
            "input": args.input,
            "frames": frames,
            "tracked": tracked,
            "tracker_fps": fps,
            "estimates": args.out,
            "metrics": summary.metrics,
        });
        println!("{}", serde_json::to_string_pretty(&out).unwrap_or_default());
        return;
    }
    println!("{name}: {tracked} of {frames} frames tracked, {fps:.0} fps (tracker only, this machine)");
    if let Some(m) = &summary.metrics {
        println!(
            "against the truth: ADD-AUC {:.2}%, ADI-AUC {:.2}%, position RMSE {:.2} cm, rotation RMSE {:.2} deg, max {:.2} cm / {:.2} deg",
            m.add_auc_percent,
            m.adi_auc_percent,
            m.position_rmse_cm,
            m.rotation_rmse_deg,
            m.max_position_error_cm,
            m.max_rotation_error_deg
        );
        if let (Some(v), Some(w)) = (m.linear_velocity_rmse_cmps, m.angular_velocity_rmse_degps) {
            println!("velocity RMSE {v:.2} cm/s, {w:.2} deg/s");
        }
    }
    if let Some(out) = &args.out {
        println!("estimates written to {}", out.display());
    }
}
