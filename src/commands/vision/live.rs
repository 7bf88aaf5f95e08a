//! `slidetrack vision track --live --rig rig.toml`: a tracker online on the
//! rig's RGB-D camera (`[rgbd]`: V4L2 colour and depth nodes, or a recording
//! standing in for them), until Ctrl-C, `--duration` or the end of a
//! recording. With `--out`, the paired and registered frames (`/rgbd/*`),
//! the estimates (`/estimate/*/<tracker>`) and, on a replayed simulated
//! session, its truth (`/sim/object`) are recorded on the run's clock.

use anyhow::{Context, Result};
use serde_json::json;
use slidetrack_experiment::vision::live::{LiveOptions, LiveSummary, LiveVisionRun};

use crate::cli::VisionTrackArgs as TrackArgs;

pub fn run(args: &TrackArgs, quiet: bool) -> Result<()> {
    let rig_path = args.rig.as_deref().context("--live needs --rig rig.toml")?;
    let options = LiveOptions {
        rig: rig_path,
        kind: args.tracker.kind(),
        input_options: args.input_options(),
        pose_reset: args.pose_reset,
        duration_s: args.duration,
        out: args.out.as_deref(),
        overwrite: args.overwrite,
    };
    let live = LiveVisionRun::open(&options)?;
    if !quiet {
        eprintln!("tracking live on the [rgbd] camera of {} (Ctrl-C stops)", rig_path.display());
    }
    let stop = crate::commands::stop_flag("closing the session");
    let summary = live.run(&stop)?;
    report(args, &summary);
    if let Some(measurements) = &summary.measurement_summary {
        eprintln!("{measurements}");
    }
    Ok(())
}

fn report(args: &TrackArgs, summary: &LiveSummary) {
    for line in summary.stream_counts.lines() {
        tracing::info!("{line}");
    }
    if args.json {
        let out = json!({
            "tracker": args.tracker.kind().name(),
            "rig": args.rig,
            "frames": summary.frames,
            "tracked": summary.tracked,
            "seconds": summary.seconds,
            "tracker_fps": summary.tracker_fps,
            "pairing": summary.pairing,
            "streams": summary.streams,
            "estimates": args.out,
            "metrics": summary.metrics,
        });
        println!("{}", serde_json::to_string_pretty(&out).unwrap_or_default());
        return;
    }
    let name = args.tracker.kind().name();
    println!(
        "{name} live: {} of {} frames tracked in {:.1} s, {:.0} fps (tracker only)",
        summary.tracked, summary.frames, summary.seconds, summary.tracker_fps
    );
    let p = &summary.pairing;
    println!(
        "pairing: {} pairs, {} colour and {} depth frames unpaired, {} pairs skipped while the tracker was behind",
        p.pairs, p.unpaired_color, p.unpaired_depth, p.skipped_pairs
    );
    for line in summary.stream_counts.lines() {
        println!("{line}");
    }
    if let Some(m) = &summary.metrics {
        println!(
            "against the recording's truth: ADD-AUC {:.2}%, position RMSE {:.2} cm, rotation RMSE {:.2} deg",
            m.add_auc_percent, m.position_rmse_cm, m.rotation_rmse_deg
        );
    }
    if let Some(out) = &args.out {
        println!("frames and estimates written to {}", out.display());
    }
}
