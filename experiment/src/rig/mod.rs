//! Rigs ready to run a trial: the simulated rig, and the real rig of a rig
//! TOML's `[hw]` table ([`hw`]). (The replay rig is built from its session,
//! in `crate::replay`.)

#[cfg(all(feature = "devices", target_os = "linux"))]
mod hw;

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::Arc;

use anyhow::{Context, Result, bail};
use slidetrack_calibration::{Dictionary, MarkerTracker, SlidingAxis, encode_jpeg, marker_pattern};
use slidetrack_control::{GraspProfile, Protocol, ProtocolConfig, Rig};
use slidetrack_core::{
    ActuatorCommand, ActuatorSpec, Camera, CameraIntrinsics, Clock, DeviceError, ErrorKind, FingerMap,
    HandActuator, HandMonitor, SimClock, TactileInfo, TactileSource, WallClock,
};
use slidetrack_session::LiveTap;
use slidetrack_sim::camera::SimCameraRenderer;
use slidetrack_sim::{HandKind, ObjectConfig, SimCamera, SimDevices, Stream, stream_seed};

#[cfg(all(feature = "devices", target_os = "linux"))]
pub use crate::v4l2_intrinsics::v4l2_intrinsics;
#[cfg(all(feature = "devices", target_os = "linux"))]
pub use hw::describe;

use crate::marker::{LiveMarkers, MarkerSource};
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

/// The simulated rig of `spec`'s trial, with its camera when asked for.
pub fn build_sim_rig(spec: &TrialSpec) -> Result<RigSetup> {
    // In real time the clock starts when the trial first reads it: setting
    // up the camera's renderer and the session takes a moment the simulated
    // devices must not have spent already (their first scans would be stale).
    let clock: Arc<dyn Clock> =
        if spec.realtime { Arc::new(WallClock::start_on_first_use()) } else { Arc::new(SimClock::new()) };
    let object = spec.object;
    spec.rig.sim.check_object(object)?;
    let sim = SimDevices::new(&spec.rig.sim, object, spec.seed, spec.trial, clock.clone());
    let tactile_info = sim.tactile.info();
    let geometry = &spec.rig.geometry;
    let (camera, markers) = if spec.camera {
        let marker = marker_pattern(&spec.rig.marker.dictionary, spec.rig.marker.id)
            .context("cannot make the marker for the simulated camera")?;
        let seed = stream_seed(spec.seed, spec.trial, Stream::Camera);
        let renderer =
            SimCameraRenderer::new(spec.rig.camera.clone(), object.appearance.clone(), marker, seed)
                .context("cannot set up the simulated camera")?;
        let camera = SimCamera::new(
            sim.world.clone(),
            renderer,
            geometry.object_start_in_hand_m,
            geometry.sliding_axis_in_hand,
        )?;
        // libjpeg-turbo through OpenCV: several times faster than the built-in encoder.
        let quality = camera.jpeg_quality();
        let camera = camera.with_encoder(Box::new(move |image| match encode_jpeg(image, quality) {
            Ok(encoded) => Some(encoded),
            Err(e) => {
                tracing::warn!("sim camera: {e}");
                None
            }
        }));
        let markers = marker_tracking(spec, camera.hand_from_camera(), camera.intrinsics())?;
        (Some(Box::new(camera) as Box<dyn Camera>), Some(Box::new(markers) as Box<dyn MarkerSource>))
    } else {
        (None, None)
    };
    let hand_monitor = Some(Box::new(sim.hand_monitor()) as Box<dyn HandMonitor>);
    let rig = Rig {
        tactile: Box::new(sim.tactile),
        hand: Box::new(sim.hand),
        camera,
        clock,
        truth: Some(Box::new(sim.truth)),
        hand_monitor,
    };
    Ok(RigSetup {
        rig,
        tactile_info,
        markers,
        rig_name: "sim".into(),
        extra_metadata: BTreeMap::new(),
        rgbd: None,
        rgbd_frames: None,
    })
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

/// The protocol of a trial of `object` on `rig`, whose sliding cycles last
/// `cycles_duration_s` seconds, reading the fingers through `fingers` and
/// commanding a hand that accepts what `actuator` says: the same for a live
/// trial and its replay.
pub fn protocol_for(
    rig: &RigConfig,
    object: &ObjectConfig,
    cycles_duration_s: f64,
    fingers: FingerMap,
    actuator: &ActuatorSpec,
) -> Protocol {
    let e = &object.experiment;
    Protocol::for_actuator(
        ProtocolConfig {
            settings: rig.protocol.clone(),
            profile: GraspProfile {
                max_counts: e.grasp_max_counts,
                min_counts: e.grasp_min_counts,
                period_s: e.period_s,
                sharpness: e.sharpness,
            },
            travel_limit_m: e.travel_limit_m,
            cycles_duration_s,
        },
        fingers,
        actuator,
    )
}

/// What the hand of `rig` accepts, from its configuration (a replay has no
/// hand to ask).
pub fn configured_actuator(rig: &RigConfig) -> ActuatorSpec {
    match rig.hw.as_ref().map(|hw| &hw.hand) {
        Some(slidetrack_drivers::config::HandDevice::Can(c)) => {
            ActuatorSpec::FingerVolts { max_volts: c.max_volts }
        }
        Some(slidetrack_drivers::config::HandDevice::Robotiq(r)) => ActuatorSpec::Gripper(r.model.spec()),
        _ if rig.sim.hand == HandKind::Gripper => ActuatorSpec::Gripper(rig.sim.gripper.spec()),
        _ => ActuatorSpec::FingerVolts { max_volts: rig.sim.max_volts },
    }
}

/// The rig of `spec`, simulated or real, once it is clear that its session
/// file may be written.
pub fn build_rig(kind: RigKind, spec: &TrialSpec) -> Result<RigSetup> {
    build_rig_with(kind, spec, HandUse::Drive)
}

/// [`build_rig`], opening the hand actuator or not. With [`HandUse::Watch`]
/// the rig's hand is an [`UndrivenHand`] (the simulated hand, never
/// commanded, on the simulated rig).
pub fn build_rig_with(kind: RigKind, spec: &TrialSpec, hand: HandUse) -> Result<RigSetup> {
    if spec.path.exists() && !spec.overwrite {
        bail!("session file {} already exists; pass --overwrite to replace it", spec.path.display());
    }
    match kind {
        RigKind::Sim => build_sim_rig(spec),
        #[cfg(all(feature = "devices", target_os = "linux"))]
        RigKind::Hw => hw::build_hw_rig(spec, hand),
        #[cfg(not(all(feature = "devices", target_os = "linux")))]
        RigKind::Hw => {
            let _ = hand;
            bail!(
                "--rig hw needs the real devices' backends, and this slidetrack was built without them \
                 (the `devices` feature, Linux only)"
            )
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A real-time simulated rig whose set-up took a while (the camera's
    /// renderer, the session file): its first scan is fresh, not the first
    /// of a backlog the devices accumulated meanwhile (a trial with the
    /// camera used to abort at once on data 400 ms old).
    #[test]
    fn a_real_time_rig_starts_its_clock_with_the_trial_not_at_set_up() {
        let rig = RigConfig::default();
        let object = ObjectConfig::load("box").expect("box");
        let spec = TrialSpec {
            rig: &rig,
            object: &object,
            seed: 1,
            trial: 0,
            duration_s: 1.0,
            camera: false,
            realtime: true,
            overwrite: true,
            path: PathBuf::from("unused.mcap"),
            live: None,
        };
        let mut setup = build_sim_rig(&spec).expect("rig");
        std::thread::sleep(std::time::Duration::from_millis(300));
        let scan = setup.rig.tactile.read().expect("scan");
        let age_s = setup.rig.clock.now().secs_since(scan.t);
        assert!(age_s < 0.1, "the first scan was {:.0} ms old", age_s * 1e3);
    }
}
