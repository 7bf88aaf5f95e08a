//! A vision tracker on the rig's `[rgbd]` camera beside a tactile trial
//! (`track --rig hw --vision maskukf|roft`), fed by the sources that need no
//! network (`aruco`, `external`), started from its first pose measurement.
//! The camera runs on the trial's clock, so its frames and estimates share
//! the session's time line. On a replay of such a session, the same tracker
//! runs on its recorded frames with the masks and poses recorded beside them.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use anyhow::{Context, Result};
use slidetrack_core::Clock;
use slidetrack_drivers::rgbd_config::RgbdCameraConfig;
use slidetrack_session::{ChannelMessage, ReadOptions, RgbdColor, SessionInfo};
use slidetrack_vision::input::{RgbdSource, SessionRgbd};
use slidetrack_vision::live::LiveTracking;
use slidetrack_vision::sources::{ExternalConfig, SessionMeasurements};
use slidetrack_vision::{PoseReset, TrackerKind, TrackerSettings};

use super::camera::{self, StreamCounts};
use super::input::{InputOptions, check_pose_reset, load_model, own_measurements};
use super::shared_camera::SharedFrames;
use super::{Measurements, Metadata, TrackerStart};
use crate::rig_config::RigConfig;
use crate::tracking::VisionEnd;

/// The vision tracker of a hardware trial and its camera, ready to run.
pub struct CameraVision {
    /// The tracker with its measurement source.
    pub tracking: LiveTracking,
    /// The camera's colour and depth, paired and registered, or the
    /// recorded frames of a replayed session.
    pub camera: Box<dyn RgbdSource + Send>,
    /// What each stream of a live camera counted.
    pub streams: Option<StreamCounts>,
    /// Keys for the session's metadata: the tracker, its model, its inputs.
    pub metadata: Metadata,
    /// With the trial (a live camera) or at the end of the recorded frames.
    pub end: VisionEnd,
    /// The tracker records the frames it tracks (`false`: the camera,
    /// shared with the marker, records every frame itself).
    pub records_frames: bool,
}

/// The options of a vision tracker on a camera.
#[derive(Clone)]
pub struct CameraVisionOptions<'a> {
    /// The tracker.
    pub kind: TrackerKind,
    /// The object model (a mesh or point cloud file); on a replay, the one
    /// the session names when `None`.
    pub model: Option<&'a str>,
    /// Scale of the model's coordinates to metres (0.001 for millimetres).
    pub model_scale: f64,
    /// Where masks and poses come from on a live camera: `Aruco` or `External`.
    pub measurements: Measurements,
    /// The marker on the object, for `Aruco`.
    pub aruco_config: Option<&'a Path>,
    /// The socket of `External`.
    pub external: ExternalConfig,
    /// MaskUKF: start again at a pose measurement this far from the estimate.
    pub pose_reset: Option<PoseReset>,
}

/// The camera table and the model a tracker on a hardware rig needs,
/// checked before the rig's devices are opened.
pub fn requirements<'a>(
    options: &CameraVisionOptions<'a>,
    rig: &'a RigConfig,
    rig_path: &Path,
) -> Result<(&'a RgbdCameraConfig, &'a str)> {
    let cfg = rig.rgbd.as_ref().with_context(|| {
        format!(
            "{}: --vision on a hardware rig tracks its RGB-D camera, and there is no [rgbd] table \
             (docs/examples/rgbd-rig.toml shows one)",
            rig_path.display()
        )
    })?;
    let model_spec = options.model.context(
        "--vision on a hardware rig needs --vision-model (the object's mesh or point cloud, in metres)",
    )?;
    check_pose_reset(options.pose_reset, options.kind)?;
    if options.measurements == Measurements::Aruco && options.aruco_config.is_none() {
        anyhow::bail!(
            "--vision-measurements aruco (the default) needs --aruco-config FILE, the marker on the object"
        );
    }
    Ok((cfg, model_spec))
}

/// Opens the `[rgbd]` camera of `rig` (read from `rig_path`) on `clock` and
/// sets up the tracker of `options` on it.
pub fn open(
    options: &CameraVisionOptions<'_>,
    rig: &RigConfig,
    rig_path: &Path,
    clock: Arc<dyn Clock>,
) -> Result<CameraVision> {
    let (cfg, model_spec) = requirements(options, rig, rig_path)?;
    let rig_dir = rig_path.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
    let camera = camera::open(cfg, rig_dir, clock)?;
    let replayed = camera.replay.clone();
    let (pair, streams) = camera.split();
    let mut vision = on_camera(options, model_spec, Box::new(pair), replayed)?;
    vision.streams = Some(streams);
    Ok(vision)
}

/// The tracker of `options` on the pairs of the `[rgbd]` camera that the
/// rig opened shared (`[hw.camera] kind = "rgbd"`): the camera records the
/// frames, the tracker its measurements and estimates.
pub fn open_shared(
    options: &CameraVisionOptions<'_>,
    rig: &RigConfig,
    rig_path: &Path,
    frames: SharedFrames,
    replayed: Option<(PathBuf, i128)>,
) -> Result<CameraVision> {
    let (_, model_spec) = requirements(options, rig, rig_path)?;
    let mut vision = on_camera(options, model_spec, Box::new(frames), replayed)?;
    vision.records_frames = false;
    Ok(vision)
}

/// The tracker of `options` on `camera`'s frames.
fn on_camera(
    options: &CameraVisionOptions<'_>,
    model_spec: &str,
    camera: Box<dyn RgbdSource + Send>,
    replayed: Option<(PathBuf, i128)>,
) -> Result<CameraVision> {
    let session = replayed.as_ref().map(|(p, _)| (p.as_path(), ReadOptions::default()));
    let model = load_model(model_spec, options.model_scale, session)
        .with_context(|| format!("--vision-model {model_spec}"))?;
    let measurements = options.measurements;
    let input = InputOptions {
        model: model_spec,
        model_scale: options.model_scale,
        object: None,
        measurements,
        init: TrackerStart::Measurement,
        recover: false,
        aruco_config: options.aruco_config,
        external: Some(options.external.clone()),
    };
    let intrinsics = camera.intrinsics().clone();
    let source = own_measurements(&input, &model, &intrinsics)?;
    let kind = options.kind;
    let mut metadata = Metadata::from([
        ("vision_tracker".to_string(), kind.name().to_string()),
        ("vision_model".to_string(), model.origin.clone()),
        ("vision_measurements".to_string(), format!("{measurements:?}").to_lowercase()),
    ]);
    if let Some((path, offset_ns)) = &replayed {
        metadata.insert("rgbd_replay".into(), path.display().to_string());
        // Session time minus recording time of the replayed recording (ns).
        metadata.insert("rgbd_replay_offset_ns".into(), offset_ns.to_string());
    }
    let settings = TrackerSettings { maskukf_pose_reset: options.pose_reset, ..TrackerSettings::default() };
    let tracking = LiveTracking::new(kind, model, intrinsics, &settings, source)?;
    let end = VisionEnd::WithTheTrial;
    Ok(CameraVision { tracking, camera, streams: None, metadata, end, records_frames: true })
}

/// True when `session` recorded RGB-D frames (`/rgbd/color`).
pub fn has_frames(session: &Path) -> Result<bool> {
    let info = SessionInfo::read(session, ReadOptions::default())?;
    Ok(info.channel(RgbdColor::TOPIC).is_some_and(|c| c.message_count > 0))
}

/// The tracker of `options` on the recorded frames of `session`, fed by its
/// recorded masks and poses (`/vision/mask`, `/vision/pose`); the model is
/// `options.model` or the one the session names.
pub fn open_recorded(options: &CameraVisionOptions<'_>, session: &Path) -> Result<CameraVision> {
    let kind = options.kind;
    check_pose_reset(options.pose_reset, kind)?;
    let info = SessionInfo::read(session, ReadOptions::default())?;
    let recorded = info.metadata.get("slidetrack").and_then(|m| m.get("vision_model")).cloned();
    let model_spec = options.model.map(str::to_string).or(recorded).with_context(|| {
        format!("{}: the session names no vision model; give --vision-model", session.display())
    })?;
    let model = load_model(&model_spec, options.model_scale, Some((session, ReadOptions::default())))
        .with_context(|| format!("vision model {model_spec}"))?;
    let frames = SessionRgbd::open(session, ReadOptions::default())?;
    let measurements = Box::new(SessionMeasurements::open(session, ReadOptions::default())?);
    let intrinsics = frames.intrinsics().clone();
    let metadata = Metadata::from([
        ("vision_tracker".to_string(), kind.name().to_string()),
        ("vision_model".to_string(), model.origin.clone()),
        ("vision_measurements".to_string(), "input".to_string()),
    ]);
    let settings = TrackerSettings { maskukf_pose_reset: options.pose_reset, ..TrackerSettings::default() };
    let tracking = LiveTracking::new(kind, model, intrinsics, &settings, measurements)?;
    // A replay reads faster than real time: the frames are tracked to their end.
    let camera = Box::new(frames);
    Ok(CameraVision {
        tracking,
        camera,
        streams: None,
        metadata,
        end: VisionEnd::WithItsFrames,
        records_frames: true,
    })
}
