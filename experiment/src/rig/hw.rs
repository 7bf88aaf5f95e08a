//! The real rig: the devices the `[hw]` table of the rig TOML names, on the
//! host's monotonic clock. Roles left to `sim` use the simulated rig's
//! devices on the same wall clock; `port = "emulated"` puts the serial
//! backend in front of the simulated sensors through a pseudo-terminal.

use std::path::Path;
use std::sync::Arc;

use anyhow::{Context, Result, bail};
use nalgebra::Isometry3;
use slidetrack_calibration::encode_jpeg;
use slidetrack_control::Rig;
use slidetrack_core::{
    Camera, CameraIntrinsics, Clock, HandActuator, HandMonitor, TactileSource, TruthSource, WallClock,
};
use slidetrack_drivers::V4l2Camera;
use slidetrack_drivers::can_hand::backend::CanHand;
use slidetrack_drivers::config::{
    CameraDevice, EMULATED_PORT, HandDevice, HwRigConfig, RobotiqConfig, TactileDevice, V4l2CameraConfig,
};
use slidetrack_drivers::robotiq::backend::{
    EmulatedRobotiqGripper, EmulatedRobotiqMonitor, RobotiqGripper, RobotiqMonitor,
};
use slidetrack_sim::camera::SimCameraRenderer;
use slidetrack_sim::{HandKind, SharedWorld, SimActuator, SimCamera, SimDevices, SimHandMonitor};

use super::marker_thread::detect_off_the_loop;
use super::ros2_tactile::open_ros2_tactile;
use super::trial::{HandUse, RigSetup, TrialSpec, UndrivenHand, marker_tracking};
use crate::marker::MarkerSource;
use crate::v4l2_intrinsics::v4l2_intrinsics;
use crate::vision::camera as rgbd_camera;
use crate::vision::shared_camera::{SharedFrames, SharedRgbd};

/// A one-line description of the devices, for the log.
pub fn describe(hw: &HwRigConfig) -> String {
    let tactile = hw.tactile.describe();
    let camera = match &hw.camera {
        CameraDevice::None => "none".to_string(),
        CameraDevice::Sim => "sim".to_string(),
        CameraDevice::V4l2(v) => format!("V4L2 {}", v.device),
        CameraDevice::Rgbd(_) => "the [rgbd] camera".to_string(),
    };
    let hand = match &hw.hand {
        HandDevice::Sim => "sim".to_string(),
        HandDevice::Can(h) => format!("CAN {}", h.interface),
        HandDevice::Robotiq(r) => format!("Robotiq {} {}", r.model.name(), r.port),
    };
    format!("rig {}: tactile {tactile}, camera {camera}, hand {hand}", hw.name)
}

/// The marker detection of a camera, when there is one.
type Markers = Option<Box<dyn MarkerSource>>;

/// A camera whose slow set-up (marker, renderer, calibration) is done.
enum PreparedCamera {
    Sim(Box<SimCameraRenderer>),
    V4l2(Box<V4l2CameraConfig>, CameraIntrinsics),
    /// The `[rgbd]` camera at `hand_from_camera`: its intrinsics, and so the
    /// marker's detection, are known once it is open.
    Rgbd(Isometry3<f64>),
}

/// The `[rgbd]` camera shared by the marker, a vision tracker and the recording.
struct Shared {
    camera: SharedRgbd,
    frames: SharedFrames,
    markers: Box<dyn MarkerSource>,
}

/// The devices of `spec.rig.hw`, opened and started.
///
/// Slow set-up comes first; then the session clock starts, the hand and the
/// camera open, and the tactile device, whose scans pace the trial, opens
/// last, so that no backlog of scans builds up before the trial reads them.
///
/// With [`HandUse::Watch`] the hand actuator is never opened (no heartbeat,
/// no release frames): the rig's hand is an [`UndrivenHand`], and a
/// simulated hand is built only when something else needs the simulated world.
pub fn build_hw_rig(spec: &TrialSpec, hand_use: HandUse) -> Result<RigSetup> {
    let Some(hw) = spec.rig.hw.as_ref() else {
        bail!(
            "--rig hw needs a [hw] table in the rig configuration (--config rig.toml) that names the devices; \
             see docs/hardware.md"
        );
    };
    tracing::info!("{}", describe(hw));
    let drive = hand_use == HandUse::Drive;
    let Emulation { gripper_on_world } = emulation(spec, hw, drive)?;
    let (prepared, markers) = prepare_camera(spec, &hw.camera)?;

    let clock: Arc<dyn Clock> = Arc::new(WallClock::start());
    let needs_world = hw.tactile.feels_simulated_world()
        || (drive && matches!(hw.hand, HandDevice::Sim))
        || gripper_on_world
        || matches!(prepared, Some(PreparedCamera::Sim(_)));
    let sim = needs_world
        .then(|| SimDevices::new(&spec.rig.sim, spec.object, spec.seed, spec.trial, Arc::clone(&clock)));
    let mut hand_monitor = sim.as_ref().map(|s| Box::new(s.hand_monitor()) as Box<dyn HandMonitor>);
    let (sim_tactile, sim_hand, sim_truth, world) = match sim {
        Some(s) => (Some(s.tactile), Some(s.hand), Some(s.truth), Some(s.world)),
        None => (None, None, None, None),
    };
    let (hand, driver_monitor) = match (&hw.hand, sim_hand, world.as_ref()) {
        (HandDevice::Robotiq(r), Some(sim_hand), Some(world)) if gripper_on_world => {
            // The emulator serves the simulated gripper itself: the rig talks
            // Modbus to it through a pty, the world moves as it is told.
            let monitor = Box::new(SimHandMonitor::new(world.clone()));
            let gripper =
                EmulatedRobotiqGripper::serving(Box::new(sim_hand), monitor, r, Arc::clone(&clock))?;
            let driver_monitor = Box::new(gripper.monitor()) as Box<dyn HandMonitor>;
            (Box::new(gripper) as Box<dyn HandActuator>, Some(driver_monitor))
        }
        (_, sim_hand, _) => open_hand(&hw.hand, sim_hand, drive, &clock)?,
    };
    if driver_monitor.is_some() {
        hand_monitor = driver_monitor;
    }
    let (camera, shared) = match prepared {
        Some(PreparedCamera::Rgbd(hand_from_camera)) => {
            let (color, shared) = open_shared(spec, hand_from_camera, &clock)?;
            (Some(color), Some(shared))
        }
        prepared => (open_camera(spec, prepared, world.as_ref(), &clock)?, None),
    };
    let sim_rate = spec.rig.sim.tactile_rate_hz;
    let truth =
        sim_truth.filter(|_| hw.tactile.feels_simulated_world()).map(|t| Box::new(t) as Box<dyn TruthSource>);
    let simulated = sim_tactile.map(|t| Box::new(t) as Box<dyn TactileSource>);
    let tactile = match &hw.tactile {
        TactileDevice::Ros2(r) => open_ros2_tactile(r, Arc::clone(&clock))?,
        device => device.open(simulated, sim_rate, Arc::clone(&clock))?,
    };
    if world.is_some() && !hw.tactile.feels_simulated_world() {
        tracing::warn!("the simulated hand or camera does not feel the real sensors: the loop is open");
    }
    let tactile_info = tactile.info();
    let rig = Rig { tactile, hand, camera, clock, truth, hand_monitor };
    let mut setup = RigSetup {
        rig,
        tactile_info,
        markers,
        rig_name: hw.name.clone(),
        extra_metadata: std::collections::BTreeMap::new(),
        rgbd: None,
        rgbd_frames: None,
        image_encoder: None,
    };
    if let Some(Shared { camera, frames, markers }) = shared {
        if let Some((path, offset_ns)) = &camera.replay {
            setup.extra_metadata.insert("rgbd_replay".into(), path.display().to_string());
            setup.extra_metadata.insert("rgbd_replay_offset_ns".into(), offset_ns.to_string());
        }
        (setup.markers, setup.rgbd, setup.rgbd_frames) = (Some(markers), Some(camera), Some(frames));
    }
    // A whole-frame search for the marker takes tens of ms: off the control loop.
    detect_off_the_loop(&mut setup)?;
    Ok(setup)
}

/// A monitor of the hand's status, when its driver reads one.
type HandWatch = Option<Box<dyn HandMonitor>>;

/// The hand actuator (an [`UndrivenHand`] unless `drive`), and the monitor
/// of a hand whose own driver reads its status.
fn open_hand(
    hand: &HandDevice,
    sim_hand: Option<SimActuator>,
    drive: bool,
    clock: &Arc<dyn Clock>,
) -> Result<(Box<dyn HandActuator>, HandWatch)> {
    Ok(match (hand, sim_hand) {
        (HandDevice::Robotiq(r), _) if !drive => (Box::new(UndrivenHand), Some(watch_robotiq(r, clock)?)),
        _ if !drive => (Box::new(UndrivenHand), None),
        (HandDevice::Sim, Some(h)) => (Box::new(h), None),
        (HandDevice::Can(c), _) => (Box::new(CanHand::open(c)?), None),
        (HandDevice::Robotiq(r), _) => {
            let (gripper, monitor) = open_robotiq(r, clock)?;
            (gripper, Some(monitor))
        }
        (HandDevice::Sim, None) => bail!("internal: the simulated hand was not built"),
    })
}

/// Opens (and activates) the Robotiq gripper, or its emulator for
/// `port = "emulated"`, with a monitor of the status its link thread reads.
fn open_robotiq(
    r: &RobotiqConfig,
    clock: &Arc<dyn Clock>,
) -> Result<(Box<dyn HandActuator>, Box<dyn HandMonitor>)> {
    if r.port == EMULATED_PORT {
        let gripper = EmulatedRobotiqGripper::start(r, Arc::clone(clock))?;
        let monitor = Box::new(gripper.monitor());
        return Ok((Box::new(gripper), monitor));
    }
    let gripper = RobotiqGripper::open(r, Arc::clone(clock))?;
    let monitor = Box::new(gripper.monitor());
    Ok((Box::new(gripper), monitor))
}

/// Which devices are emulated on the simulated world.
struct Emulation {
    /// The Robotiq gripper is the simulated gripper behind its emulator (the
    /// sensors feel it).
    gripper_on_world: bool,
}

/// What `hw` emulates, refusing combinations whose emulated sensors would
/// feel no hand.
fn emulation(spec: &TrialSpec, hw: &HwRigConfig, drive: bool) -> Result<Emulation> {
    let emulated = hw.tactile.is_emulated();
    let gripper_on_world = drive && emulated && emulated_robotiq(&hw.hand);
    if emulated && drive && !matches!(hw.hand, HandDevice::Sim) && !gripper_on_world {
        bail!(
            "hw.tactile port = \"emulated\" (serial or slcan, or url = \"emulated\") needs hw.hand kind = \"sim\" \
             or kind = \"robotiq\" with port = \"emulated\": the emulated sensors feel the simulated hand"
        );
    }
    if gripper_on_world && spec.rig.sim.hand != HandKind::Gripper {
        bail!(
            "hw.hand kind = \"robotiq\" with port = \"emulated\" beside emulated sensors needs [sim] hand = \"gripper\": \
             the emulated Robotiq is the simulated gripper the sensors feel"
        );
    }
    Ok(Emulation { gripper_on_world })
}

/// True for a Robotiq hand whose port is the emulator.
fn emulated_robotiq(hand: &HandDevice) -> bool {
    matches!(hand, HandDevice::Robotiq(r) if r.port == EMULATED_PORT)
}

/// Watches the Robotiq gripper's status without activating or commanding it.
fn watch_robotiq(r: &RobotiqConfig, clock: &Arc<dyn Clock>) -> Result<Box<dyn HandMonitor>> {
    if r.port == EMULATED_PORT {
        return Ok(Box::new(EmulatedRobotiqMonitor::start(r, Arc::clone(clock))?));
    }
    Ok(Box::new(RobotiqMonitor::watch(r, Arc::clone(clock))?))
}

/// The slow set-up of the camera (marker, renderer, calibration) and its
/// marker detection, before any device opens.
fn prepare_camera(spec: &TrialSpec, camera: &CameraDevice) -> Result<(Option<PreparedCamera>, Markers)> {
    Ok(match (camera, spec.camera) {
        (CameraDevice::None, _) | (_, false) => (None, None),
        (CameraDevice::Sim, true) => {
            let renderer = super::trial::sim_camera_renderer(spec)?;
            let markers = marker_tracking(spec, *renderer.hand_from_camera(), renderer.intrinsics())?;
            (Some(PreparedCamera::Sim(Box::new(renderer))), Some(markers))
        }
        (CameraDevice::V4l2(v), true) => {
            let intrinsics = v4l2_intrinsics(v)?;
            let hand_from_camera = v.placement.hand_from_camera().context("hw.camera.placement")?;
            let markers = marker_tracking(spec, hand_from_camera, &intrinsics)?;
            (Some(PreparedCamera::V4l2(v.clone(), intrinsics)), Some(markers))
        }
        (CameraDevice::Rgbd(r), true) => {
            let hand_from_camera = r.placement.hand_from_camera().context("hw.camera.placement")?;
            (Some(PreparedCamera::Rgbd(hand_from_camera)), None)
        }
    })
}

/// Opens the `[rgbd]` camera on `clock`, shared: its colour frames as the
/// trial's camera, with the marker's detection in them.
fn open_shared(
    spec: &TrialSpec,
    hand_from_camera: Isometry3<f64>,
    clock: &Arc<dyn Clock>,
) -> Result<(Box<dyn Camera>, Shared)> {
    use slidetrack_drivers::rgbd_config::{ReplayPace, RgbdCameraConfig};
    let Some(cfg) = spec.rig.rgbd.as_ref() else {
        bail!("hw.camera kind = \"rgbd\" is the camera of the [rgbd] table, and there is none");
    };
    // The rig TOML's relative paths were made absolute when it was loaded.
    let live = rgbd_camera::open(cfg, Path::new("."), Arc::clone(clock)).context("the [rgbd] camera")?;
    let every_frame = matches!(cfg, RgbdCameraConfig::Recording(r) if r.pace == ReplayPace::EveryFrame);
    let (camera, color, frames) = SharedRgbd::new(live, every_frame);
    let markers = marker_tracking(spec, hand_from_camera, camera.intrinsics())?;
    Ok((Box::new(color), Shared { camera, frames, markers }))
}

/// Opens the prepared camera: the simulated one on `world`, or the V4L2 device.
fn open_camera(
    spec: &TrialSpec,
    prepared: Option<PreparedCamera>,
    world: Option<&SharedWorld>,
    clock: &Arc<dyn Clock>,
) -> Result<Option<Box<dyn Camera>>> {
    Ok(match (prepared, world) {
        (None, _) => None,
        (Some(PreparedCamera::Sim(renderer)), Some(world)) => {
            let g = &spec.rig.geometry;
            let camera = SimCamera::new(
                Arc::clone(world),
                *renderer,
                g.object_start_in_hand_m,
                g.sliding_axis_in_hand,
            )?;
            let quality = camera.jpeg_quality();
            Some(Box::new(camera.with_encoder(Box::new(move |image| encode_jpeg(image, quality).ok()))))
        }
        (Some(PreparedCamera::Sim(_)), None) => bail!("internal: the simulated world was not built"),
        (Some(PreparedCamera::V4l2(v, intrinsics)), _) => {
            Some(Box::new(V4l2Camera::open(&v, intrinsics, Arc::clone(clock))?))
        }
        (Some(PreparedCamera::Rgbd(_)), _) => bail!("internal: the [rgbd] camera is opened shared"),
    })
}

#[cfg(test)]
mod tests {
    use slidetrack_core::parse_toml;

    use super::*;
    use crate::rig_config::RigConfig;

    #[test]
    fn the_docs_hardware_example_is_a_valid_rig_config() {
        let readme = include_str!("../../../docs/hardware.md");
        let section = readme.find("# Hardware").expect("a Hardware section");
        let start = section + readme[section..].find("```toml\n").expect("a toml block") + 8;
        let end = start + readme[start..].find("```").expect("closed block");
        let cfg: RigConfig = parse_toml(&readme[start..end], "docs/hardware.md").unwrap();
        cfg.validate().unwrap();
        let hw = cfg.hw.expect("a [hw] table");
        assert_eq!(
            describe(&hw),
            "rig lab-hand: tactile serial /dev/ttyACM0, camera V4L2 /dev/video0, hand CAN can0"
        );
    }

    #[test]
    fn the_docs_xela_server_example_is_a_valid_rig_config() {
        let readme = include_str!("../../../docs/hardware.md");
        let kind = readme.find("url = \"ws://192.168.0.21:5000\"").expect("a xela_ws example");
        let start = readme[..kind].rfind("```toml\n").expect("a toml block") + 8;
        let end = start + readme[start..].find("```").expect("closed block");
        let block: String = readme[start..end].lines().map(|l| format!("{}\n", l.trim_start())).collect();
        let cfg: RigConfig = parse_toml(&block, "docs/hardware.md").unwrap();
        cfg.validate().unwrap();
        let hw = cfg.hw.expect("a [hw] table");
        assert_eq!(
            describe(&hw),
            "rig xela-gripper: tactile xela_server ws://192.168.0.21:5000, camera sim, hand sim"
        );
    }

    #[test]
    fn the_docs_robotiq_example_is_a_valid_rig_config() {
        let readme = include_str!("../../../docs/hardware.md");
        let kind = readme.find("kind = \"robotiq\"\nport").expect("a robotiq example");
        let start = readme[..kind].rfind("```toml\n").expect("a toml block") + 8;
        let end = start + readme[start..].find("```").expect("closed block");
        let cfg: RigConfig = parse_toml(&readme[start..end], "docs/hardware.md").unwrap();
        cfg.validate().unwrap();
        let hw = cfg.hw.expect("a [hw] table");
        assert_eq!(describe(&hw), "rig robotiq-rig: tactile sim, camera sim, hand Robotiq 2f85 /dev/ttyUSB0");
    }

    #[test]
    fn a_rig_config_with_hw_round_trips_through_the_session_metadata() {
        let text = "[hw]\nname = \"x\"\n[hw.tactile]\nkind = \"serial\"\nport = \"emulated\"\n";
        let cfg: RigConfig = parse_toml(text, "rig.toml").unwrap();
        let back: RigConfig = parse_toml(&toml::to_string(&cfg).unwrap(), "metadata").unwrap();
        assert_eq!(back, cfg);
        let plain = toml::to_string(&RigConfig::default()).unwrap();
        assert!(!plain.contains("[hw"), "no [hw] table for the simulated rig");
    }
}
