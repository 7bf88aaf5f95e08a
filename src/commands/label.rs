//! `slidetrack label`: ground truth from the ArUco marker, written into each session.

use anyhow::{Context, Result, bail};
use indicatif::{ProgressBar, ProgressStyle};
use serde_json::json;
use slidetrack_experiment::labelling::{
    AxisSource, CvParams, GroundTruthSlot, HandFrame, InHandRecord, InHandSettings, JointTuning,
    LabelOptions, LabelReport, SmootherSettings, Tuning, hand_calibration, in_hand_jointly_into,
    in_hand_options, label_session, smoother_params, tune_sessions,
};

use crate::cli::{AxisArg, LabelArgs, SlotArg};

pub fn run(args: &LabelArgs, quiet: bool) -> Result<()> {
    let mut options = options(args)?;
    let joint = if args.jointly {
        let (params, joint) = tune_sessions(&args.files, &options)?;
        options.params = params;
        options.tuning = Tuning::Joint(joint);
        if !args.json {
            println!("{}", joint_text(&params, &joint));
        }
        Some(joint)
    } else {
        None
    };
    let joint_in_hand = if args.jointly { in_hand_jointly_for(args, &mut options)? } else { None };
    let (summaries, failures) = label_files(args, &options, quiet)?;
    if args.json {
        let out = match joint {
            Some(j) => json!({
                "joint_tuning": joint_json(&options.params, &j),
                "in_hand": joint_in_hand,
                "sessions": summaries,
            }),
            None => serde_json::Value::Array(summaries),
        };
        println!("{}", serde_json::to_string_pretty(&out)?);
    }
    if !failures.is_empty() {
        bail!(
            "{} of {} files could not be labelled (left unchanged): {}",
            failures.len(),
            args.files.len(),
            failures.join(", ")
        );
    }
    Ok(())
}

/// The labelling options of `args`.
fn options(args: &LabelArgs) -> Result<LabelOptions> {
    let smoother = SmootherSettings {
        thesis: args.thesis,
        q_position: args.q_position,
        q_velocity: args.q_velocity,
        r: args.r,
        gate: args.gate,
        no_gate: args.no_gate,
        tune: args.tune,
        reacquire_after: args.reacquire_after,
    };
    let in_hand = InHandSettings {
        off: args.no_in_hand,
        from_file: args.in_hand.as_deref(),
        reacquire_after: args.reacquire_after,
        hand_from_camera: args.hand_from_camera.as_deref(),
        contact_load_counts: args.contact_load,
        hold_settle_s: args.hold_settle,
        hold_from_start: args.hold_from_start,
    };
    Ok(LabelOptions {
        params: smoother_params(&smoother)?,
        axis: match args.axis {
            AxisArg::Recorded => AxisSource::Recorded,
            AxisArg::Config => AxisSource::Config,
            AxisArg::Estimate => AxisSource::Estimate,
        },
        hand: hand_calibration(args.hand_calibration.as_deref())?,
        recover: args.recover,
        dry_run: args.dry_run,
        tuning: if args.tune { Tuning::PerSession } else { Tuning::Off },
        slot: match args.slot {
            SlotArg::Default => GroundTruthSlot::Default,
            SlotArg::Thesis => GroundTruthSlot::Thesis,
        },
        in_hand: in_hand_options(&in_hand)?,
        in_hand_joint: None,
    })
}

/// Labels each file, one line (or JSON summary) each; the summaries and
/// the files that failed (with several files, a failure does not stop the others).
fn label_files(
    args: &LabelArgs,
    options: &LabelOptions,
    quiet: bool,
) -> Result<(Vec<serde_json::Value>, Vec<String>)> {
    let bar = if quiet || args.files.len() < 2 {
        ProgressBar::hidden()
    } else {
        ProgressBar::new(args.files.len() as u64)
    };
    bar.set_style(
        ProgressStyle::with_template("labelling [{bar:30}] {pos}/{len} {msg}")
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
    );
    let mut summaries = Vec::new();
    let mut failures = Vec::new();
    for file in &args.files {
        bar.set_message(file.display().to_string());
        match label_session(file, options) {
            Ok(report) => {
                if args.json {
                    summaries.push(to_json(&report));
                } else {
                    bar.suspend(|| println!("{}", to_text(&report)));
                }
            }
            Err(e) if args.files.len() == 1 => return Err(e.into()),
            Err(e) => {
                bar.suspend(|| eprintln!("error: {}", crate::one_line(&e.into())));
                failures.push(file.display().to_string());
            }
        }
        bar.inc(1);
    }
    bar.finish_and_clear();
    Ok((summaries, failures))
}

/// With `--jointly`: the pose smoother's densities tuned on all the files
/// and the contact frame estimated from all their holds, put into
/// `options` (and saved with `--save-in-hand`); `None` without in-hand
/// labelling or without a hold.
fn in_hand_jointly_for(args: &LabelArgs, options: &mut LabelOptions) -> Result<Option<InHandRecord>> {
    let labels_in_hand = options.in_hand.is_some();
    let Some(record) = in_hand_jointly_into(&args.files, args.recover, options)? else {
        if labels_in_hand && args.save_in_hand.is_some() {
            bail!("no session has a hold with marker poses: nothing to save in --save-in-hand");
        }
        return Ok(None);
    };
    if !args.json {
        println!("{}", in_hand_text(&record));
    }
    if let Some(path) = &args.save_in_hand {
        std::fs::write(path, serde_json::to_string_pretty(&record)?)
            .with_context(|| format!("cannot write {}", path.display()))?;
    }
    Ok(Some(record))
}

/// The joint in-hand estimate in a few lines.
fn in_hand_text(r: &InHandRecord) -> String {
    let c = &r.contact;
    let f = |v: [f64; 3]| format!("({:.3}, {:.3}, {:.3})", v[0], v[1], v[2]);
    format!(
        "in the hand: pose noise {:.2} mm, {:.2} deg; contact normal {}, x axis {}, grip point {} m\n  {}",
        r.pose.r_position_m2.sqrt() * 1e3,
        r.pose.r_orientation_rad2.sqrt().to_degrees(),
        f(c.normal),
        f(c.x_axis),
        f(c.origin_m),
        c.how
    )
}

/// The tuned densities in one line (R also as the marker's standard deviation).
fn densities_text(p: &CvParams) -> String {
    format!(
        "q_p = {:.3e} m^2/s, q_v = {:.3e} m^2/s^3, R = {:.3e} m^2 (marker noise {:.3} mm)",
        p.q_position_m2_per_s,
        p.q_velocity_m2_per_s3,
        p.r_m2,
        p.r_m2.sqrt() * 1e3
    )
}

fn joint_text(p: &CvParams, j: &JointTuning) -> String {
    format!(
        "tuned jointly on {} sessions ({} marker positions): {}; log-likelihood {:.1}",
        j.sessions,
        j.measurements,
        densities_text(p),
        j.log_likelihood
    )
}

fn joint_json(p: &CvParams, j: &JointTuning) -> serde_json::Value {
    json!({
        "sessions": j.sessions,
        "marker_positions": j.measurements,
        "q_position_m2_per_s": p.q_position_m2_per_s,
        "q_velocity_m2_per_s3": p.q_velocity_m2_per_s3,
        "r_m2": p.r_m2,
        "gate_max_mahalanobis2": p.gate.map(|g| g.max_mahalanobis2),
        "gate_reacquire_after": p.gate.and_then(|g| g.reacquire_after),
        "log_likelihood": j.log_likelihood,
        "evaluations": j.evaluations,
    })
}

fn to_text(r: &LabelReport) -> String {
    let rmse = r.rmse.map_or(String::new(), |e| {
        format!("; vs /sim/truth: RMSE {:.3} mm, {:.2} mm/s", e.position_m * 1e3, e.velocity_mps * 1e3)
    });
    let action = if r.written { "labelled" } else { "computed (dry run, not written)" };
    let tuned = if r.tuned {
        format!("\n  tuned: {}; log-likelihood {:.1}", densities_text(&r.params), r.log_likelihood)
    } else {
        String::new()
    };
    let in_hand = r.in_hand.as_ref().map_or(String::new(), |h| {
        format!(
            "\n  in the hand: {} poses ({} marker poses, {} rejected), hold of {} scans{}",
            h.poses,
            h.measured,
            h.rejected,
            h.hold_scans,
            if h.contact.is_none() { " (no contact frame)" } else { "" }
        )
    });
    format!(
        "{}: {} scans {action}; {} camera frames, {} marker positions ({} missing), {} outliers rejected{rmse}{tuned}{in_hand}{}",
        r.path.display(),
        r.samples,
        r.frames,
        r.detections,
        r.missing_detections,
        r.rejected_outliers,
        r.hand_frame.as_ref().map_or(String::new(), hand_frame_text)
    )
}

/// The hand frame of a labelling with a hand calibration, in one line.
fn hand_frame_text(h: &HandFrame) -> String {
    let s = h.axes.sliding;
    format!(
        "\n  hand frame: camera from {}; sliding axis ({:.3}, {:.3}, {:.3}) in the hand, from {}",
        h.calibration.display(),
        s.x,
        s.y,
        s.z,
        h.geometry_from
    )
}

/// The hand frame as JSON: the calibration, the geometry and its axes.
fn hand_frame_json(h: &HandFrame) -> serde_json::Value {
    let t = h.hand_from_camera.translation.vector;
    let q = h.hand_from_camera.rotation.coords;
    json!({
        "calibration": h.calibration.display().to_string(),
        "hand_from_camera": { "translation_m": [t.x, t.y, t.z], "quaternion_xyzw": [q.x, q.y, q.z, q.w] },
        "geometry": h.geometry,
        "geometry_from": h.geometry_from,
        "sliding_axis_in_hand": h.axes.sliding.as_slice(),
        "closing_axis_in_hand": h.axes.closing.as_slice(),
        "contact": h.contact,
    })
}

fn to_json(r: &LabelReport) -> serde_json::Value {
    let mut out = json!({
        "file": r.path.display().to_string(),
        "samples": r.samples,
        "camera_frames": r.frames,
        "marker_positions": r.detections,
        "missing_detections": r.missing_detections,
        "rejected_outliers": r.rejected_outliers,
        "written": r.written,
        "axis_in_camera": r.axis_in_camera,
        "params": {
            "q_position_m2_per_s": r.params.q_position_m2_per_s,
            "q_velocity_m2_per_s3": r.params.q_velocity_m2_per_s3,
            "r_m2": r.params.r_m2,
            "gate_max_mahalanobis2": r.params.gate.map(|g| g.max_mahalanobis2),
            "gate_reacquire_after": r.params.gate.and_then(|g| g.reacquire_after),
            "tuned": r.tuned,
            "log_likelihood": r.log_likelihood,
        },
        "in_hand": r.in_hand.as_ref().map(|h| json!({
            "poses": h.poses,
            "marker_poses": h.measured,
            "rejected_poses": h.rejected,
            "log_likelihood": h.log_likelihood,
            "hold_scans": h.hold_scans,
            "pose_smoother": h.params,
            "contact": h.contact,
        })),
        "rmse": r.rmse.map(|e| json!({
            "position_m": e.position_m,
            "velocity_mps": e.velocity_mps,
            "samples": e.samples,
        })),
    });
    // Only with a hand calibration: the output without one stays as it was.
    if let (Some(h), Some(map)) = (&r.hand_frame, out.as_object_mut()) {
        map.insert("hand_frame".into(), hand_frame_json(h));
        map.insert("axis_from".into(), r.axis_from.clone().into());
    }
    out
}
