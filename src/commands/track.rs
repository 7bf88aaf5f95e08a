//! `slidetrack track`: the controlled-sliding experiment with the dEKF live
//! on every tactile scan and a causal Kalman filter on the marker, recorded
//! to one session and shown in the terminal; on the replay rig, the same on a
//! recorded session.

use std::path::PathBuf;
use std::sync::{Arc, Mutex};

use anyhow::{Context, Result, bail};
use indicatif::{ProgressBar, ProgressStyle};
use slidetrack_calibration::ground_truth::default_params;
use slidetrack_estimators::dekf::DekfModel;
use slidetrack_experiment::dekf_run::load_model;
use slidetrack_experiment::replay::{ReplayOptions, ReplaySession, check_rate};
use slidetrack_experiment::rig::{RigKind, RigSetup, TrialSpec, build_rig};
use slidetrack_experiment::rig_config::RigConfig;
use slidetrack_experiment::tracking::{LiveStatus, LiveTrackers};
use slidetrack_experiment::trial::{ExtensionFactory, prepare_out_dir, record_trial_with};
use slidetrack_experiment::vision_inhand::{InHandVision, InHandVisionConfig};
use slidetrack_live::LiveServer;
use slidetrack_sim::ObjectConfig;
use slidetrack_vision::TrackerKind;

use crate::cli::{RigArg, TrackArgs};

pub fn run(args: &TrackArgs, quiet: bool) -> Result<()> {
    if !(args.run.duration.is_finite() && args.run.duration > 0.0) {
        bail!("--duration must be a positive number of seconds, got {}", args.run.duration);
    }
    if args.vision.is_some() && (args.run.rig == RigArg::Hw || args.run.no_camera) {
        bail!(
            "--vision runs on the simulated rig's rendered RGB-D scene: it needs --rig sim (or a replay of a \
             simulated session) and the camera; on a real RGB-D camera run `slidetrack vision track --live \
             --rig RIG.toml` (with --measurements aruco or external) beside the tactile tracking"
        );
    }
    let model = load_model(&args.model)?;
    let kind = match args.run.rig {
        RigArg::Replay => return replay(args, &model, quiet),
        RigArg::Sim => RigKind::Sim,
        RigArg::Hw => RigKind::Hw,
    };
    let object = ObjectConfig::load(&args.run.object)?;
    let rig = RigConfig::load(args.run.config.as_deref())?;
    let path = args.out.clone().unwrap_or_else(|| {
        PathBuf::from("sessions")
            .join(format!("{}-s{}-t{:03}-track.mcap", object.name, args.run.seed, args.trial))
    });
    prepare_parent(&path)?;
    let live = super::live::start(&args.run.live)?;
    let spec = TrialSpec {
        rig: &rig,
        object: &object,
        seed: args.run.seed,
        trial: args.trial,
        duration_s: args.run.duration,
        camera: !args.run.no_camera,
        realtime: args.run.realtime,
        overwrite: args.run.overwrite,
        path,
        live: live.as_ref().map(LiveServer::tap),
    };
    let setup = build_rig(kind, &spec)?;
    let rate = setup.tactile_info.rate_hz;
    let expected = model.meta.tactile_rate_hz;
    if (rate - expected).abs() > 0.05 * expected {
        bail!(
            "{}: the tactile source runs at {rate:.1} Hz, but the model was trained at {expected:.1} Hz",
            args.model.display()
        );
    }
    let tracked = track_on(args, model, setup, &spec, quiet);
    super::live::finish(live);
    tracked
}

/// `track --rig replay`: the trackers on a replay of `--session`.
fn replay(args: &TrackArgs, model: &DekfModel, quiet: bool) -> Result<()> {
    let Some(input) = args.run.session.as_ref() else {
        bail!("--rig replay needs --session FILE, the recorded session to replay");
    };
    let session = ReplaySession::open(input)?;
    check_rate(&session, model)?;
    if args.vision.is_some() && !session.has_truth {
        bail!(
            "{}: --vision on a replay renders the in-hand scene from the recorded /sim/truth, which this \
             session does not have",
            input.display()
        );
    }
    let path = args.out.clone().unwrap_or_else(|| {
        let stem = input.file_stem().map_or("session".into(), |s| s.to_string_lossy().into_owned());
        PathBuf::from("sessions").join(format!("{stem}-replay.mcap"))
    });
    if std::fs::canonicalize(input).ok() == std::fs::canonicalize(&path).ok() {
        bail!("--out must differ from the replayed session {}", input.display());
    }
    prepare_parent(&path)?;
    let mut spec = session.trial_spec(path, args.run.overwrite);
    spec.camera &= !args.run.no_camera;
    if spec.path.exists() && !spec.overwrite {
        bail!("session file {} already exists; pass --overwrite to replace it", spec.path.display());
    }
    let live = super::live::start(&args.run.live)?;
    spec.live = live.as_ref().map(LiveServer::tap);
    let setup = session.rig(ReplayOptions { camera: spec.camera, truth: true })?;
    let tracked = track_on(args, model.clone(), setup, &spec, quiet);
    super::live::finish(live);
    tracked
}

/// Creates the directory of `path` when it has one.
fn prepare_parent(path: &std::path::Path) -> Result<()> {
    match path.parent().filter(|d| !d.as_os_str().is_empty()) {
        Some(dir) => prepare_out_dir(dir),
        None => Ok(()),
    }
}

/// Runs the trial of `spec` on `setup` with the trackers live, and prints
/// their errors against the simulator's truth.
fn track_on(
    args: &TrackArgs,
    model: DekfModel,
    setup: RigSetup,
    spec: &TrialSpec,
    quiet: bool,
) -> Result<()> {
    let (rig, object) = (spec.rig, spec.object);
    let display = if quiet { ProgressBar::hidden() } else { ProgressBar::new_spinner() };
    display.set_style(
        ProgressStyle::with_template("{msg}").unwrap_or_else(|_| ProgressStyle::default_spinner()),
    );
    display.enable_steady_tick(std::time::Duration::from_millis(100));
    let status = Arc::new(Mutex::new(LiveStatus::default()));
    let model_name = args.model.file_name().map_or(String::new(), |n| n.to_string_lossy().into_owned());
    let with_marker = setup.markers.is_some();
    let vision = match args.vision {
        Some(kind) => {
            let g = &rig.geometry;
            let config = InHandVisionConfig::new(kind.into(), spec.seed ^ u64::from(spec.trial));
            Some(
                InHandVision::new(
                    &config,
                    &rig.camera,
                    &object.geometry,
                    g.object_start_in_hand_m,
                    g.sliding_axis_in_hand,
                )
                .context("cannot set up the vision tracker")?,
            )
        }
        None => None,
    };
    let record_rgbd = args.record_rgbd;
    let (s, d) = (status.clone(), display.clone());
    let extension: ExtensionFactory = Box::new(move |logger, tactile| {
        let marker = with_marker.then(default_params);
        let show = Box::new(move |line: &str| d.set_message(line.to_string()));
        let mut trackers = LiveTrackers::new(logger, tactile, &model, &model_name, marker, s, show)?;
        if let Some(v) = vision {
            trackers = trackers.with_vision(v.with_recording(logger.clone(), record_rgbd)?);
        }
        Ok(Box::new(trackers) as Box<_>)
    });
    let stop = super::stop_flag();
    let mut progress = |_t: slidetrack_core::TimeNs| {};
    let report = record_trial_with(setup, spec, &stop, &mut progress, Some(extension))?;
    display.finish_and_clear();

    println!("{}", report.summary_line());
    let status = status.lock().map(|s| s.clone()).unwrap_or_default();
    println!("  dEKF: {} steps; /tactile/derivative, /estimate/dekf recorded", status.dekf_steps);
    if let Some([p, v, base]) = status.dekf_errors.rmse() {
        println!(
            "  dEKF against the simulator's truth until the release: position RMSE {p:.3} cm (zero-motion baseline {base:.3} cm), velocity RMSE {v:.3} cm/s"
        );
    }
    if let Some([p, v, _]) = status.marker_errors.rmse() {
        println!(
            "  marker KF (/estimate/aruco) against the simulator's truth: position RMSE {p:.3} cm, velocity RMSE {v:.3} cm/s"
        );
    }
    if let (Some(kind), Some([p, v, _])) = (args.vision, status.vision_errors.rmse()) {
        println!(
            "  vision ({}) along the sliding axis against the simulator's truth: position RMSE {p:.3} cm, velocity RMSE {v:.3} cm/s",
            TrackerKind::from(kind).name()
        );
    }
    if let Some(reason) = &report.outcome.abort {
        bail!("the trial was aborted: {reason}; {} keeps what was recorded", report.path.display());
    }
    Ok(())
}
