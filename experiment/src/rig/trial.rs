//! What a trial's rig is built from ([`TrialSpec`]) and into ([`RigSetup`]),
//! shared by the simulated and the real rig.

use std::collections::BTreeMap;
use std::path::PathBuf;

use anyhow::{Context, Result};
use slidetrack_calibration::{
    Board, Dictionary, MarkerDetector, MarkerTracker, SlidingAxis, board_patterns, marker_pattern,
};
use slidetrack_control::Rig;
use slidetrack_core::{
    ActuatorCommand, ActuatorSpec, CameraIntrinsics, DeviceError, ErrorKind, HandActuator, TactileInfo,
};
use slidetrack_session::LiveTap;
use slidetrack_sim::camera::{BoardPrint, SimCameraRenderer};
use slidetrack_sim::{ObjectConfig, Stream, stream_seed};

use crate::image_encoder::ImageEncodeFn;
use crate::marker::{LiveBoard, LiveMarkers, MarkerSource};
use crate::rig_config::RigConfig;
use crate::vision::shared_camera::{SharedFrames, SharedRgbd};

/// Which rig runs a trial.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RigKind {
    /// The simulated rig (physics model of the hand, object and sensors).
    Sim,
    /// The real rig, with the devices of the rig configuration's `[hw]` table.
    Hw,
}

/// What to run.
pub struct TrialSpec<'a> {
    /// The rig.
    pub rig: &'a RigConfig,
    /// The object.
    pub object: &'a ObjectConfig,
    /// Seed of the simulated rig.
    pub seed: u64,
    /// Trial number.
    pub trial: u32,
    /// Duration of the sliding cycles (s).
    pub duration_s: f64,
    /// Render, detect and record the camera.
    pub camera: bool,
    /// Run on wall-clock time.
    pub realtime: bool,
    /// Replace an existing session file.
    pub overwrite: bool,
    /// Session file to write.
    pub path: PathBuf,
    /// Where the recorder also hands what it writes, for a live viewer
    /// (`--live`); never waited for.
    pub live: Option<LiveTap>,
}

/// A rig ready to run, with what the recorder needs to know about it.
pub struct RigSetup {
    /// The devices.
    pub rig: Rig,
    /// Facts about the tactile source, for the taxel layout.
    pub tactile_info: TactileInfo,
    /// The marker detection of the camera's frames, when there is a camera.
    pub markers: Option<Box<dyn MarkerSource>>,
    /// `sim`, `replay`, or the name of the real rig.
    pub rig_name: String,
    /// Further keys of the session's metadata record (a replay names its recording).
    pub extra_metadata: BTreeMap<String, String>,
    /// The RGB-D camera that is also the marker camera (`[hw.camera] kind =
    /// "rgbd"`): it records its colour, depth and calibration once started
    /// on the session, and is stopped before the session is finished.
    pub rgbd: Option<SharedRgbd>,
    /// Its pairs, for a vision tracker that takes them.
    pub rgbd_frames: Option<SharedFrames>,
    /// The encoder of a camera that delivers its frames unencoded (the
    /// simulated camera when not in real time), for the observer to run
    /// on a thread of its own ([`crate::image_encoder`]).
    pub image_encoder: Option<ImageEncodeFn>,
}

/// Whether a rig drives its hand.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum HandUse {
    /// Open the hand actuator: the controlled-sliding protocol commands it.
    Drive,
    /// Never open the hand actuator (`slidetrack record`: something else may
    /// drive the hand); only watch it where that needs no commands.
    Watch,
}

/// A hand that is not driven: commands are refused, a release does nothing.
pub struct UndrivenHand;

impl HandActuator for UndrivenHand {
    fn spec(&self) -> ActuatorSpec {
        ActuatorSpec::FingerVolts { max_volts: 0.0 }
    }

    fn command(&mut self, _command: &ActuatorCommand) -> Result<(), DeviceError> {
        Err(DeviceError::new(ErrorKind::Other, "hand", "this rig does not drive the hand"))
    }

    fn release(&mut self) -> Result<(), DeviceError> {
        Ok(())
    }

    fn device(&self) -> &str {
        "undriven hand"
    }
}

/// The simulated camera's renderer of `spec`'s trial: the object's marker,
/// or the rig's board, from OpenCV's dictionaries.
pub(crate) fn sim_camera_renderer(spec: &TrialSpec) -> Result<SimCameraRenderer> {
    let seed = stream_seed(spec.seed, spec.trial, Stream::Camera);
    let (config, appearance) = (spec.rig.camera.clone(), spec.object.appearance.clone());
    let marker = &spec.rig.marker;
    let renderer = match &marker.board {
        None => {
            let pattern = marker_pattern(&marker.dictionary, marker.id)
                .context("cannot make the marker for the simulated camera")?;
            SimCameraRenderer::new(config, appearance, pattern, seed)
        }
        Some(layout) => {
            let markers = board_patterns(layout, &Dictionary::from_name(&marker.dictionary)?)
                .context("cannot make the board for the simulated camera")?;
            SimCameraRenderer::with_board(
                config,
                appearance,
                BoardPrint { layout: layout.clone(), markers },
                seed,
            )
        }
    };
    renderer.context("cannot set up the simulated camera")
}

/// Marker (or board) detection for a camera at `hand_from_camera` with `intrinsics`.
pub fn marker_tracking(
    spec: &TrialSpec,
    hand_from_camera: nalgebra::Isometry3<f64>,
    intrinsics: &CameraIntrinsics,
) -> Result<Box<dyn MarkerSource>> {
    let axis = SlidingAxis::new(hand_from_camera, spec.rig.geometry.sliding_axis_in_hand.into())?;
    let dictionary = Dictionary::from_name(&spec.rig.marker.dictionary)?;
    if let Some(layout) = &spec.rig.marker.board {
        return Ok(Box::new(LiveBoard {
            board: Board::new(layout.clone(), &dictionary)?,
            detector: MarkerDetector::new(dictionary)?,
            intrinsics: intrinsics.clone(),
            projector: axis.projector(),
        }));
    }
    Ok(Box::new(LiveMarkers {
        tracker: MarkerTracker::new(dictionary, spec.rig.marker.id)?,
        marker_size_m: spec.object.appearance.marker_size_m,
        intrinsics: intrinsics.clone(),
        projector: axis.projector(),
    }))
}
