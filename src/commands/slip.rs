//! `slidetrack slip`: the grasp-state detector run offline over recorded
//! sessions (`slidetrack_experiment::grasp_eval`), reported as tables or JSON.

use std::path::Path;

use anyhow::Result;
use slidetrack_experiment::dataset::expand;
use slidetrack_experiment::grasp_eval::{
    GraspDetectorConfig, SessionScores, SlipAuc, SlipReport, SlipSummary, evaluate,
};

use crate::cli::SlipArgs;

pub fn run(args: &SlipArgs) -> Result<()> {
    let files = expand(&args.files)?;
    let report = evaluate(&files, GraspDetectorConfig::default())?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        print_text(&report);
    }
    Ok(())
}

/// A number with `decimals`, or `-`.
fn opt(x: Option<f64>, decimals: usize) -> String {
    x.map_or_else(|| "-".into(), |v| format!("{v:.decimals$}"))
}

/// The file name of a session, for tables.
fn name(file: &str) -> String {
    Path::new(file).file_stem().map_or_else(|| file.to_string(), |n| n.to_string_lossy().into_owned())
}

fn print_text(report: &SlipReport) {
    let d = &report.detector;
    let slip = d.slip.map_or_else(
        || "none (never slipping)".to_string(),
        |h| format!("enter {} / exit {} counts/s", h.enter_score, h.exit_score),
    );
    println!(
        "grasp detector: contact {} counts, drop ratio {}, release opening {} mm, slip hysteresis {slip}",
        d.contact_load_counts,
        d.drop_load_ratio,
        d.release_opening_m * 1e3
    );
    println!("slip score: {}", report.slip_score);
    println!(
        "times: s of session log time; delays: first `dropped` minus the release / the marker's last sighting"
    );
    println!();
    println!(
        "{:<34} {:>7} {:>6} {:>9} {:>6} {:>8} {:>8} {:>8} {:>8} {:>8} {:>5} {:>7}",
        "session",
        "dropped",
        "scans",
        "peak L",
        "min",
        "release",
        "marker",
        "dropped",
        "d rel",
        "d mark",
        "drops",
        "held s"
    );
    for s in &report.sessions {
        print_session(s);
    }
    println!();
    print_summary(&report.summary);
    print_slip(report);
}

fn print_session(s: &SessionScores) {
    let flag = s.dropped.map_or("?", |d| if d { "dropped" } else { "kept" });
    println!(
        "{:<34} {:>7} {:>6} {:>9.0} {:>6} {:>8} {:>8} {:>8} {:>8} {:>8} {:>5} {:>7.1}",
        name(&s.file),
        flag,
        s.scans,
        s.peak_load_counts,
        opt(s.lowest_load_ratio, 3),
        opt(s.tactile_release_s, 2),
        opt(s.marker_last_seen_s, 2),
        opt(s.first_dropped_s, 2),
        opt(s.delay_after_release_s, 3),
        opt(s.delay_after_marker_s, 3),
        s.hold.dropped_entries,
        s.hold.held_s
    );
}

fn print_summary(s: &SlipSummary) {
    println!(
        "drops: {} of {} dropped sessions read `dropped`, {} within {} s of the tactile release; delay \
         after the release median {} s, max {} s; after the marker's last sighting median {} s ({})",
        s.drops_flagged,
        s.dropped_sessions,
        s.drops_detected,
        s.window_s,
        opt(s.delay_median_s, 3),
        opt(s.delay_max_s, 3),
        opt(s.delay_after_marker_median_s, 3),
        s.delay_after_marker_range_s.map_or_else(|| "-".into(), |[a, b]| format!("{a:.3} to {b:.3}"))
    );
    println!(
        "false alarms: {} `dropped` entries over {} kept sessions, {:.1} min held: {} per held minute ({} per 5 min)",
        s.false_alarms,
        s.kept_sessions,
        s.kept_held_min,
        opt(s.false_alarms_per_held_min, 3),
        opt(s.false_alarms_per_5_held_min, 3)
    );
    let unknown = s.sessions - s.dropped_sessions - s.kept_sessions;
    if unknown > 0 {
        println!("({unknown} sessions without a dropped flag in their metadata are in neither count)");
    }
}

fn auc_row(label: &str, a: &SlipAuc) {
    println!(
        "{:<34} {:>6} {:>6} {:>10} {:>10}",
        label,
        a.rows,
        a.slip_rows,
        opt(a.auc_slip_score, 3),
        opt(a.auc_robot_speed, 3)
    );
}

fn print_slip(report: &SlipReport) {
    let Some(pooled) = &report.summary.slip else { return };
    println!();
    println!(
        "slip label ROC-AUC, one row per tactile scan: the label follows the marker's motion and is \
         confounded with the robot's speed, whose AUC is beside the score's"
    );
    println!("{:<34} {:>6} {:>6} {:>10} {:>10}", "session", "rows", "slip", "AUC score", "AUC |v|");
    for s in &report.sessions {
        if let Some(a) = &s.slip {
            auc_row(&name(&s.file), a);
        }
    }
    auc_row("pooled", pooled);
}
