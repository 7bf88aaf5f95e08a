//! Rigs ready to run a trial: the simulated rig, and the real rig of a rig
//! TOML's `[hw]` table ([`hw`]). (The replay rig is built from its session,
//! in `crate::replay`.)

#[cfg(all(feature = "devices", target_os = "linux"))]
mod hw;
mod marker_thread;
#[cfg(all(feature = "devices", target_os = "linux"))]
mod ros2_tactile;
mod trial;

use std::collections::BTreeMap;
use std::sync::Arc;

use anyhow::{Result, bail};
use slidetrack_calibration::encode_jpeg;
use slidetrack_control::{GraspProfile, Protocol, ProtocolConfig, Rig};
use slidetrack_core::{
    ActuatorSpec, Camera, Clock, FingerMap, HandMonitor, SimClock, TactileSource, WallClock,
};
use slidetrack_sim::{HandKind, ObjectConfig, SimCamera, SimDevices};

use crate::image_encoder::ImageEncodeFn;

#[cfg(all(feature = "devices", target_os = "linux"))]
pub use crate::v4l2_intrinsics::v4l2_intrinsics;
#[cfg(all(feature = "devices", target_os = "linux"))]
pub use hw::describe;

use crate::rig_config::RigConfig;
use trial::sim_camera_renderer;
pub use trial::{HandUse, RigKind, RigSetup, TrialSpec, UndrivenHand, marker_tracking};

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
    let (camera, markers, image_encoder) = if spec.camera {
        let renderer = sim_camera_renderer(spec)?;
        let camera = SimCamera::new(
            sim.world.clone(),
            renderer,
            geometry.object_start_in_hand_m,
            geometry.sliding_axis_in_hand,
        )?;
        // libjpeg-turbo (calibration's codec): several times faster than the pure-Rust
        // encoder of `slidetrack_core`.
        let quality = camera.jpeg_quality();
        let encode: ImageEncodeFn = Box::new(move |image| match encode_jpeg(image, quality) {
            Ok(encoded) => Some(encoded),
            Err(e) => {
                tracing::warn!("sim camera: {e}");
                None
            }
        });
        // Not in real time, the observer encodes the frames on another core
        // (the same session, never a frame dropped); in real time the camera
        // encodes them, and a recorder that falls behind drops images.
        let (camera, image_encoder) = if spec.realtime {
            (camera.with_encoder(encode), None)
        } else {
            (camera.with_encoder(Box::new(|_| None)), Some(encode))
        };
        let markers = marker_tracking(spec, camera.hand_from_camera(), camera.intrinsics())?;
        (Some(Box::new(camera) as Box<dyn Camera>), Some(markers), image_encoder)
    } else {
        (None, None, None)
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
    let mut setup = RigSetup {
        rig,
        tactile_info,
        markers,
        rig_name: "sim".into(),
        extra_metadata: BTreeMap::new(),
        rgbd: None,
        rgbd_frames: None,
        image_encoder,
    };
    if spec.realtime {
        // On the host's clock, as on the real rig: the camera and its
        // marker detection off the control loop.
        marker_thread::detect_off_the_loop(&mut setup)?;
    }
    Ok(setup)
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
    use std::path::PathBuf;

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
