//! What a trial's rig is built from ([`TrialSpec`]) and into ([`RigSetup`]),
//! shared by the simulated and the real rig.

use std::collections::BTreeMap;
use std::path::PathBuf;

use anyhow::Result;
use slidetrack_calibration::{Dictionary, MarkerTracker, SlidingAxis};
use slidetrack_control::Rig;
use slidetrack_core::{
    ActuatorCommand, ActuatorSpec, CameraIntrinsics, DeviceError, ErrorKind, HandActuator, TactileInfo,
};
use slidetrack_session::LiveTap;
use slidetrack_sim::ObjectConfig;

use crate::marker::{LiveMarkers, MarkerSource};
use crate::rig_config::RigConfig;

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

/// Marker detection for a camera at `hand_from_camera` with `intrinsics`.
pub fn marker_tracking(
    spec: &TrialSpec,
    hand_from_camera: nalgebra::Isometry3<f64>,
    intrinsics: &CameraIntrinsics,
) -> Result<LiveMarkers> {
    let axis = SlidingAxis::new(hand_from_camera, spec.rig.geometry.sliding_axis_in_hand.into())?;
    Ok(LiveMarkers {
        tracker: MarkerTracker::new(Dictionary::from_name(&spec.rig.marker.dictionary)?, spec.rig.marker.id)?,
        marker_size_m: spec.object.appearance.marker_size_m,
        intrinsics: intrinsics.clone(),
        projector: axis.projector(),
    })
}
