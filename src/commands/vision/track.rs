//! `slidetrack vision track`: a tracker over a session or a directory.

use std::collections::BTreeMap;
use std::time::{Duration, Instant};

use anyhow::Result;
use indicatif::{ProgressBar, ProgressStyle};
use serde_json::json;
use slidetrack_estimators::metrics::SequenceMetrics;
use slidetrack_session::{Recorder, RecorderOptions};
use slidetrack_vision::eval::{Scored, TrackedFrame, score};
use slidetrack_vision::record::EstimateChannels;
use slidetrack_vision::sources::ExternalConfig;
use slidetrack_vision::{TrackerKind, TrackerSettings, build_tracker};

use super::inputs::{InputOptions, Prepared, check_pose_reset, prepare};
use crate::cli::VisionTrackArgs as TrackArgs;

pub fn run(args: &TrackArgs, quiet: bool) -> Result<()> {
    check_pose_reset(args.pose_reset, args.tracker.kind())?;
    let Some(input) = &args.input else {
        return super::live::run(args, quiet);
    };
    let options = InputOptions {
        model: &args.model,
        model_scale: args.model_scale,
        object: args.object.as_deref(),
        measurements: args.measurements,
        init: args.init,
        recover: args.recover,
        aruco_config: args.aruco_config.as_deref(),
        external: Some(external_config(&args.external)),
    };
    let Prepared { mut source, mut measurements, model, intrinsics, initial_pose } =
        prepare(input, &options)?;
    let kind = args.tracker.kind();
    let settings =
        TrackerSettings { initial_pose, maskukf_pose_reset: args.pose_reset, ..TrackerSettings::default() };
    let mut tracker = build_tracker(kind, &model, &intrinsics, &settings)?;
    let recorder = args.out.as_ref().map(|path| recorder(args, path, kind, &model.origin)).transpose()?;
    let channels = match &recorder {
        Some(r) => Some(EstimateChannels::register(&r.logger(), kind)?),
        None => None,
    };
    let bar = match (quiet, source.len_hint()) {
        (false, Some(n)) => ProgressBar::new(n as u64),
        _ => ProgressBar::hidden(),
    };
    bar.set_style(ProgressStyle::with_template("{bar:40} {pos}/{len} frames {eta}")?);
    let mut busy = Duration::ZERO;
    let (mut frames, mut tracked) = (0usize, 0usize);
    let mut results = Vec::new();
    let mut last_pose = None;
    while let Some(sample) = source.next_frame()? {
        let truth = sample.truth.as_ref().zip(sample.truth_mask.as_ref());
        let arrivals = measurements.on_rgbd_frame(
            &sample.frame,
            truth.map(|(t, m)| slidetrack_vision::sources::FrameTruth {
                camera_from_object: &t.camera_from_object,
                mask: m,
            }),
        )?;
        if let Some(p) = arrivals.latest_pose() {
            last_pose = Some(p.value);
        }
        let started = Instant::now();
        let state = tracker.process(&sample.frame, &arrivals)?;
        busy += started.elapsed();
        frames += 1;
        if let Some(s) = &state {
            tracked += 1;
            if let (Some(r), Some(c)) = (&recorder, &channels) {
                c.log(&r.logger(), s)?;
            }
        }
        if let Some(truth) = sample.truth {
            results.push(TrackedFrame {
                truth,
                flow_velocity: state.as_ref().and_then(|s| s.flow_velocity),
                estimate: state.map(|s| s.estimate),
                last_measured_pose: last_pose,
            });
        }
        bar.inc(1);
    }
    bar.finish_and_clear();
    if let Some(r) = recorder {
        r.finish()?;
    }
    let fps = if busy.is_zero() { 0.0 } else { frames as f64 / busy.as_secs_f64() };
    let first = results.iter().position(|f| f.estimate.is_some()).unwrap_or(results.len());
    let metrics = (!results.is_empty() && first < results.len())
        .then(|| model.object_points().map(|points| score(&results, first, Scored::Tracker, &points)))
        .transpose()?;
    report(args, frames, tracked, fps, metrics.as_ref());
    if let Some(summary) = measurements.summary() {
        eprintln!("{summary}");
    }
    Ok(())
}

/// The external source's settings from the command line.
pub(super) fn external_config(args: &crate::cli::ExternalArgs) -> ExternalConfig {
    ExternalConfig {
        listen: args.listen.clone(),
        wait_for_result: (args.external_wait_ms > 0).then(|| Duration::from_millis(args.external_wait_ms)),
        wait_for_client: (args.external_wait_client_ms > 0)
            .then(|| Duration::from_millis(args.external_wait_client_ms)),
        max_age_ns: args.external_max_age_ms.saturating_mul(1_000_000),
        send_images: args.external_send_images,
    }
}

/// The session for the estimates of `args`, with what produced them in its metadata.
fn recorder(args: &TrackArgs, path: &std::path::Path, kind: TrackerKind, model: &str) -> Result<Recorder> {
    let options = RecorderOptions { overwrite: args.overwrite, ..RecorderOptions::default() };
    let metadata = BTreeMap::from([
        ("software_version".to_string(), env!("CARGO_PKG_VERSION").to_string()),
        ("tracker".to_string(), kind.name().to_string()),
        ("input".to_string(), args.input.as_ref().map(|p| p.display().to_string()).unwrap_or_default()),
        ("model".to_string(), model.to_string()),
    ]);
    Ok(Recorder::create_with_options(path, metadata, options)?)
}

fn report(args: &TrackArgs, frames: usize, tracked: usize, fps: f64, metrics: Option<&SequenceMetrics>) {
    let name = args.tracker.kind().name();
    if args.json {
        let out = json!({
            "tracker": name,
            "input": args.input,
            "frames": frames,
            "tracked": tracked,
            "tracker_fps": fps,
            "estimates": args.out,
            "metrics": metrics,
        });
        println!("{}", serde_json::to_string_pretty(&out).unwrap_or_default());
        return;
    }
    println!("{name}: {tracked} of {frames} frames tracked, {fps:.0} fps (tracker only, this machine)");
    if let Some(m) = metrics {
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
