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
use slidetrack_experiment::tracking::{CameraVisionSummary, LiveStatus, LiveTrackers};
use slidetrack_experiment::trial::{ExtensionFactory, prepare_out_dir, record_trial_with};
use slidetrack_experiment::vision_inhand::{InHandVision, InHandVisionConfig};
use slidetrack_live::LiveServer;
use slidetrack_sim::ObjectConfig;
use slidetrack_experiment::vision::TrackerKind;
use slidetrack_experiment::vision::camera::StreamCounts;
use slidetrack_experiment::vision::camera_vision::{self, CameraVision};

use crate::cli::{RigArg, TrackArgs};

pub fn run(args: &TrackArgs, quiet: bool) -> Result<()> {
    if !(args.run.duration.is_finite() && args.run.duration > 0.0) {
        bail!("--duration must be a positive number of seconds, got {}", args.run.duration);
    }
    if args.pose_reset.is_some() && args.run.rig == RigArg::Sim {
        bail!(
            "--pose-reset is for the vision tracker on a camera (--rig hw, or a replay of its frames); \
             the simulated rig's in-hand tracker has no pose measurements to reset at"
        );
    }
    if args.vision.is_some() && args.run.rig == RigArg::Sim && args.run.no_camera {
        bail!(
            "--vision on the simulated rig tracks its rendered in-hand RGB-D scene: drop --no-camera \
             (on a hardware rig it tracks the [rgbd] camera of --config)"
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
    let camera_config = match (kind, args.vision) {
        (RigKind::Hw, Some(v)) => {
            let path = args.run.config.as_deref().context(
                "--vision on a hardware rig tracks the [rgbd] camera of the rig TOML: give --config RIG.toml",
            )?;
            camera_vision::requirements(&args.camera_vision_options(v), &rig, path)?;
            Some(path)
        }
        _ => None,
    };
    let setup = build_rig(kind, &spec)?;
    let camera_vision = match (camera_config, args.vision) {
        (Some(path), Some(v)) => {
            Some(camera_vision::open(&args.camera_vision_options(v), &rig, path, Arc::clone(&setup.rig.clock))?)
        }
        _ => None,
    };
    let rate = setup.tactile_info.rate_hz;
    let expected = model.meta.tactile_rate_hz;
    if (rate - expected).abs() > 0.05 * expected {
        bail!(
            "{}: the tactile source runs at {rate:.1} Hz, but the model was trained at {expected:.1} Hz",
            args.model.display()
        );
    }
    let tracked = track_on(args, model, setup, &spec, camera_vision, quiet);
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
    // A session with a camera's frames is tracked on them, with the masks
    // and poses recorded beside them; a simulated session without them has
    // its in-hand scene rendered again from its truth.
    let camera_vision = match args.vision {
        Some(kind) if camera_vision::has_frames(input)? => {
            Some(camera_vision::open_recorded(&args.camera_vision_options(kind), input)?)
        }
        Some(_) if !session.has_truth => bail!(
            "{}: --vision on a replay tracks the recorded RGB-D frames (/rgbd/*) or renders the in-hand \
             scene from /sim/truth, and this session has neither",
            input.display()
        ),
        _ => None,
    };
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
    if args.vision.is_some() && camera_vision.is_none() && !spec.camera {
        bail!(
            "{}: --vision renders the in-hand scene at each replayed camera frame, and this replay has \
             none (--no-camera, or a session recorded without the camera)",
            input.display()
        );
    }
    if spec.path.exists() && !spec.overwrite {
        bail!("session file {} already exists; pass --overwrite to replace it", spec.path.display());
    }
    let live = super::live::start(&args.run.live)?;
    spec.live = live.as_ref().map(LiveServer::tap);
    let setup = session.rig(ReplayOptions { camera: spec.camera, truth: true })?;
    let tracked = track_on(args, model.clone(), setup, &spec, camera_vision, quiet);
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
/// their errors against the simulator's truth. A vision tracker runs on the
/// rig's RGB-D camera when `camera_vision` is given, else (with `--vision`)
/// on the simulated in-hand scene.
fn track_on(
    args: &TrackArgs,
    model: DekfModel,
    mut setup: RigSetup,
    spec: &TrialSpec,
    camera_vision: Option<CameraVision>,
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
    let (camera_vision, streams) = match camera_vision {
        Some(CameraVision { tracking, camera, streams, metadata, end }) => {
            setup.extra_metadata.extend(metadata);
            (Some((tracking, camera, end)), streams)
        }
        None => (None, None),
    };
    let vision = match (args.vision, &camera_vision) {
        (Some(kind), None) => {
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
        _ => None,
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
        if let Some((tracking, camera, end)) = camera_vision {
            trackers = trackers.with_camera_vision(tracking.recording_to(logger)?.spawn(camera), end);
        }
        Ok(Box::new(trackers) as Box<_>)
    });
    let stop = super::stop_flag(super::RELEASING);
    let mut progress = |_t: slidetrack_core::TimeNs| {};
    let report = record_trial_with(setup, spec, &stop, &mut progress, Some(extension))?;
    display.finish_and_clear();

    println!("{}", report.summary_line());
    let status = status.lock().map(|s| s.clone()).unwrap_or_default();
    println!("  dEKF: {} steps; /tactile/derivative, /estimate/dekf recorded", status.dekf_steps);
    if let Some(grasp) = status.grasp {
        println!("  grasp detector: /estimate/slip recorded, last state {}", grasp.as_str());
    }
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
    if let (Some(summary), Some(kind)) = (&status.camera_vision, args.vision) {
        print_camera_vision(TrackerKind::from(kind), summary, streams.as_ref());
    }
    if let Some(reason) = &report.outcome.abort {
        bail!("the trial was aborted: {reason}; {} keeps what was recorded", report.path.display());
    }
    Ok(())
}

/// The summary lines of the vision tracker on the rig's camera; why it
/// stopped, if it stopped before the trial, on stderr.
fn print_camera_vision(kind: TrackerKind, s: &CameraVisionSummary, streams: Option<&StreamCounts>) {
    println!(
        "  vision ({}) on the [rgbd] camera: {} of {} frames tracked, {:.0} fps (tracker only); \
         /rgbd/*, /estimate/*/{} recorded",
        kind.name(),
        s.tracked,
        s.frames,
        s.tracker_fps,
        kind.name()
    );
    for line in streams.map(StreamCounts::lines).unwrap_or_default().iter().chain(&s.measurements) {
        println!("    {line}");
    }
    if let Some(e) = &s.error {
        eprintln!("warning: the vision tracker stopped before the trial ended: {e}");
    }
}
