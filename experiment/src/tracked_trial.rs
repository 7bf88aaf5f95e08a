//! The controlled-sliding experiment with the trackers live (`track`): the
//! dEKF on every tactile scan, a causal Kalman filter on the marker and,
//! optionally, a vision tracker (on the simulated in-hand scene, or on the
//! rig's `[rgbd]` camera), recorded to one session; on the replay rig, the
//! same on a recorded session.
//!
//! A run has two phases, so that the caller can start its live view between
//! them: [`TrackRun::prepare`] checks the options and loads the model, the
//! object and the rig (or opens the replayed session); [`TrackRun::run`]
//! opens the devices and runs the trial.

use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;
use std::sync::{Arc, Mutex};

use anyhow::{Context, Result, bail};
use slidetrack_calibration::ground_truth::default_params;
use slidetrack_estimators::dekf::DekfModel;
use slidetrack_session::LiveTap;
use slidetrack_sim::ObjectConfig;

use crate::dekf_run::load_model;
use crate::replay::{ReplayOptions, ReplaySession, check_rate};
use crate::rig::{RigKind, RigSetup, TrialSpec, build_rig};
use crate::rig_config::RigConfig;
use crate::tracking::{LiveStatus, LiveTrackers};
use crate::trial::{ExtensionFactory, TrialReport, prepare_out_dir, record_trial_with};
use crate::vision::TrackerKind;
use crate::vision::camera::StreamCounts;
use crate::vision::camera_vision::{self, CameraVision, CameraVisionOptions};
use crate::vision_inhand::{InHandVision, InHandVisionConfig};

/// The rig a tracked trial runs on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TrackRig {
    /// The simulated rig.
    Sim,
    /// The real rig of the configuration's `[hw]` table.
    Hw,
    /// A recorded session played back.
    Replay,
}

/// The options of a tracked trial.
#[derive(Clone)]
pub struct TrackOptions<'a> {
    /// The rig.
    pub rig: TrackRig,
    /// The dEKF model file.
    pub model: &'a Path,
    /// The object: a built-in name or an object TOML.
    pub object: &'a str,
    /// The rig TOML; the built-in simulated rig when `None`.
    pub config: Option<&'a Path>,
    /// The recorded session of the replay rig.
    pub session: Option<&'a Path>,
    /// Seed of the simulated rig.
    pub seed: u64,
    /// Trial number.
    pub trial: u32,
    /// Duration of the sliding cycles (s).
    pub duration_s: f64,
    /// Render, detect and record the camera.
    pub camera: bool,
    /// Run the simulated rig on wall-clock time.
    pub realtime: bool,
    /// Replace an existing session file.
    pub overwrite: bool,
    /// The session file; by default under `sessions/`.
    pub out: Option<PathBuf>,
    /// The vision tracker beside the dEKF, and its options on a camera.
    pub vision: Option<CameraVisionOptions<'a>>,
    /// With a vision tracker on the simulated scene: also record the
    /// rendered colour, depth and masks.
    pub record_rgbd: bool,
}

/// A tracked trial, checked and loaded, before any device opens.
pub struct TrackRun<'a> {
    options: TrackOptions<'a>,
    model: DekfModel,
    inputs: Inputs,
}

/// What a trial runs on.
#[expect(clippy::large_enum_variant, reason = "one value per run, moved once")]
enum Inputs {
    /// A new trial on the simulated or the real rig.
    New { kind: RigKind, object: ObjectConfig, rig: RigConfig, path: PathBuf },
    /// A replay of a recorded session.
    Replay { session: ReplaySession, camera_vision: Option<CameraVision>, path: PathBuf, camera: bool },
}

/// What the caller provides once the devices are open.
pub struct TrialHooks<'a> {
    /// The flag that stops the trial, asked for once the rig is open.
    pub stop: &'a dyn Fn() -> Arc<AtomicBool>,
    /// Receives the live status line (about ten times per second of session time).
    pub show: Box<dyn FnMut(&str)>,
}

/// What a tracked trial did.
pub struct TrackedTrial {
    /// The trial's report.
    pub report: TrialReport,
    /// What the trackers counted and their errors against the truth.
    pub status: LiveStatus,
    /// What each stream of the rig's camera counted, with a vision tracker on it.
    pub streams: Option<StreamCounts>,
}

impl<'a> TrackRun<'a> {
    /// Checks `options` and loads the model, the object and the rig, or
    /// opens the replayed session.
    pub fn prepare(options: TrackOptions<'a>) -> Result<TrackRun<'a>> {
        check(&options)?;
        let model = load_model(options.model)?;
        let kind = match options.rig {
            TrackRig::Replay => {
                let inputs = replay_inputs(&options, &model)?;
                return Ok(TrackRun { options, model, inputs });
            }
            TrackRig::Sim => RigKind::Sim,
            TrackRig::Hw => RigKind::Hw,
        };
        let object = ObjectConfig::load(options.object)?;
        let rig = RigConfig::load(options.config)?;
        let path = options.out.clone().unwrap_or_else(|| {
            PathBuf::from("sessions")
                .join(format!("{}-s{}-t{:03}-track.mcap", object.name, options.seed, options.trial))
        });
        prepare_parent(&path)?;
        Ok(TrackRun { options, model, inputs: Inputs::New { kind, object, rig, path } })
    }

    /// Opens the rig (and the vision tracker's camera) and runs the trial,
    /// handing what it records to `live` too.
    pub fn run(self, live: Option<LiveTap>, hooks: TrialHooks<'_>) -> Result<TrackedTrial> {
        let TrackRun { options, model, inputs } = self;
        match inputs {
            Inputs::New { kind, object, rig, path } => {
                let spec = TrialSpec {
                    rig: &rig,
                    object: &object,
                    seed: options.seed,
                    trial: options.trial,
                    duration_s: options.duration_s,
                    camera: options.camera,
                    realtime: options.realtime,
                    overwrite: options.overwrite,
                    path,
                    live,
                };
                let (setup, camera_vision) = open_rig(&options, kind, &spec, &model)?;
                track_on(&options, model, setup, &spec, camera_vision, hooks)
            }
            Inputs::Replay { session, camera_vision, path, camera } => {
                let mut spec = session.trial_spec(path, options.overwrite);
                spec.camera = camera;
                spec.live = live;
                let setup = session.rig(ReplayOptions { camera: spec.camera, truth: true })?;
                track_on(&options, model, setup, &spec, camera_vision, hooks)
            }
        }
    }
}

/// The checks of `options` that need nothing opened.
fn check(options: &TrackOptions<'_>) -> Result<()> {
    if !(options.duration_s.is_finite() && options.duration_s > 0.0) {
        bail!("--duration must be a positive number of seconds, got {}", options.duration_s);
    }
    let pose_reset = options.vision.as_ref().is_some_and(|v| v.pose_reset.is_some());
    if pose_reset && options.rig == TrackRig::Sim {
        bail!(
            "--pose-reset is for the vision tracker on a camera (--rig hw, or a replay of its frames); \
             the simulated rig's in-hand tracker has no pose measurements to reset at"
        );
    }
    if options.vision.is_some() && options.rig == TrackRig::Sim && !options.camera {
        bail!(
            "--vision on the simulated rig tracks its rendered in-hand RGB-D scene: drop --no-camera \
             (on a hardware rig it tracks the [rgbd] camera of --config)"
        );
    }
    Ok(())
}

/// The rig of `spec` opened, with the vision tracker on its `[rgbd]` camera
/// on a hardware rig; the tactile rate checked against the model's.
fn open_rig(
    options: &TrackOptions<'_>,
    kind: RigKind,
    spec: &TrialSpec<'_>,
    model: &DekfModel,
) -> Result<(RigSetup, Option<CameraVision>)> {
    let camera_config = match (kind, &options.vision) {
        (RigKind::Hw, Some(vision)) => {
            let path = options.config.context(
                "--vision on a hardware rig tracks the [rgbd] camera of the rig TOML: give --config RIG.toml",
            )?;
            camera_vision::requirements(vision, spec.rig, path)?;
            Some((path, vision))
        }
        _ => None,
    };
    let mut setup = build_rig(kind, spec)?;
    // The camera the rig opened shared with the marker, or the `[rgbd]` camera alone.
    let camera_vision = match (camera_config, setup.rgbd_frames.take()) {
        (Some((path, vision)), Some(frames)) => {
            let replayed = setup.rgbd.as_ref().and_then(|r| r.replay.clone());
            Some(camera_vision::open_shared(vision, spec.rig, path, frames, replayed)?)
        }
        (Some((path, vision)), None) => {
            Some(camera_vision::open(vision, spec.rig, path, Arc::clone(&setup.rig.clock))?)
        }
        (None, _) => None,
    };
    let rate = setup.tactile_info.rate_hz;
    let expected = model.meta.tactile_rate_hz;
    if (rate - expected).abs() > 0.05 * expected {
        bail!(
            "{}: the tactile source runs at {rate:.1} Hz, but the model was trained at {expected:.1} Hz",
            options.model.display()
        );
    }
    Ok((setup, camera_vision))
}

/// `track --rig replay`: the recorded session, the vision tracker on its
/// frames, and the checks of the session file to write.
fn replay_inputs(options: &TrackOptions<'_>, model: &DekfModel) -> Result<Inputs> {
    let Some(input) = options.session else {
        bail!("--rig replay needs --session FILE, the recorded session to replay");
    };
    let session = ReplaySession::open(input)?;
    check_rate(&session, model)?;
    // A session with a camera's frames is tracked on them, with the masks
    // and poses recorded beside them; a simulated session without them has
    // its in-hand scene rendered again from its truth.
    let camera_vision = match &options.vision {
        Some(vision) if camera_vision::has_frames(input)? => {
            Some(camera_vision::open_recorded(vision, input)?)
        }
        Some(_) if !session.has_truth => bail!(
            "{}: --vision on a replay tracks the recorded RGB-D frames (/rgbd/*) or renders the in-hand \
             scene from /sim/truth, and this session has neither",
            input.display()
        ),
        _ => None,
    };
    let path = options.out.clone().unwrap_or_else(|| {
        let stem = input.file_stem().map_or("session".into(), |s| s.to_string_lossy().into_owned());
        PathBuf::from("sessions").join(format!("{stem}-replay.mcap"))
    });
    if std::fs::canonicalize(input).ok() == std::fs::canonicalize(&path).ok() {
        bail!("--out must differ from the replayed session {}", input.display());
    }
    prepare_parent(&path)?;
    let camera = {
        let spec = session.trial_spec(path.clone(), options.overwrite);
        let camera = spec.camera && options.camera;
        if options.vision.is_some() && camera_vision.is_none() && !camera {
            bail!(
                "{}: --vision renders the in-hand scene at each replayed camera frame, and this replay has \
                 none (--no-camera, or a session recorded without the camera)",
                input.display()
            );
        }
        if spec.path.exists() && !spec.overwrite {
            bail!("session file {} already exists; pass --overwrite to replace it", spec.path.display());
        }
        camera
    };
    Ok(Inputs::Replay { session, camera_vision, path, camera })
}

/// Creates the directory of `path` when it has one.
fn prepare_parent(path: &Path) -> Result<()> {
    match path.parent().filter(|d| !d.as_os_str().is_empty()) {
        Some(dir) => prepare_out_dir(dir),
        None => Ok(()),
    }
}

/// The vision tracker on the simulated in-hand scene, when asked for and
/// not on a camera.
fn in_hand_vision(kind: Option<TrackerKind>, spec: &TrialSpec<'_>) -> Result<Option<InHandVision>> {
    let Some(kind) = kind else { return Ok(None) };
    let (rig, object) = (spec.rig, spec.object);
    let g = &rig.geometry;
    let config = InHandVisionConfig::new(kind, spec.seed ^ u64::from(spec.trial));
    let vision = InHandVision::new(
        &config,
        &rig.camera,
        &object.geometry,
        g.object_start_in_hand_m,
        g.sliding_axis_in_hand,
    )
    .context("cannot set up the vision tracker")?;
    Ok(Some(vision))
}

/// Runs the trial of `spec` on `setup` with the trackers live. A vision
/// tracker runs on the rig's RGB-D camera when `camera_vision` is given,
/// else (with a vision tracker asked for) on the simulated in-hand scene.
fn track_on(
    options: &TrackOptions<'_>,
    model: DekfModel,
    mut setup: RigSetup,
    spec: &TrialSpec<'_>,
    camera_vision: Option<CameraVision>,
    hooks: TrialHooks<'_>,
) -> Result<TrackedTrial> {
    let status = Arc::new(Mutex::new(LiveStatus::default()));
    let model_name = options.model.file_name().map_or(String::new(), |n| n.to_string_lossy().into_owned());
    let with_marker = setup.markers.is_some();
    let (camera_vision, streams) = match camera_vision {
        Some(CameraVision { tracking, camera, streams, metadata, end, records_frames }) => {
            setup.extra_metadata.extend(metadata);
            (Some((tracking, camera, end, records_frames)), streams)
        }
        None => (None, None),
    };
    let kind = options.vision.as_ref().map(|v| v.kind);
    let vision = if camera_vision.is_none() { in_hand_vision(kind, spec)? } else { None };
    let record_rgbd = options.record_rgbd;
    let (s, show) = (status.clone(), hooks.show);
    let extension: ExtensionFactory = Box::new(move |logger, tactile| {
        let marker = with_marker.then(default_params);
        let mut trackers = LiveTrackers::new(logger, tactile, &model, &model_name, marker, s, show)?;
        if let Some(v) = vision {
            trackers = trackers.with_vision(v.with_recording(logger.clone(), record_rgbd)?);
        }
        if let Some((tracking, camera, end, records_frames)) = camera_vision {
            let tracking = if records_frames {
                tracking.recording_to(logger)?
            } else {
                tracking.recording_estimates_to(logger)?
            };
            trackers = trackers.with_camera_vision(tracking.spawn(camera), end);
        }
        Ok(Box::new(trackers) as Box<_>)
    });
    let stop = (hooks.stop)();
    let mut progress = |_t: slidetrack_core::TimeNs| {};
    let report = record_trial_with(setup, spec, &stop, &mut progress, Some(extension))?;
    let status = status.lock().map(|s| s.clone()).unwrap_or_default();
    Ok(TrackedTrial { report, status, streams })
}
