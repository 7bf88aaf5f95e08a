//! The simulated devices: each implements its driver trait on a shared
//! [`SimWorld`], advancing it on the session clock.

use std::sync::{Arc, Mutex};

use slidetrack_core::{
    ActuatorCommand, ActuatorSpec, Clock, DeviceError, Finger, FingerReading, HandActuator, HandMonitor,
    HandStatus, PerFinger, SensorLayout, SimTruth, TactileInfo, TactileLayout, TactileSample, TactileSource,
    TimeNs, TruthSource, saturate,
};

use super::config::SimRigConfig;
use super::gripper::HandKind;
use super::gripper_device::SimGripper;
use super::object::ObjectConfig;
pub use super::shared_world::SharedWorld;
use super::shared_world::lock;
use super::tactile_model::PatchConfig;
use super::world::SimWorld;

/// The simulated devices of one trial.
pub struct SimDevices {
    /// The fingertip modules (of the gripper: the two pads').
    pub tactile: SimTactile,
    /// The hand: the three fingers or the gripper (`[sim] hand`).
    pub hand: SimActuator,
    /// The simulator's truth at each scan.
    pub truth: SimTruthTap,
    /// The world, for the camera and for tests.
    pub world: SharedWorld,
}

impl SimDevices {
    /// One trial of `object` on the simulated rig, on `clock`, from `seed` and `trial`.
    pub fn new(
        cfg: &SimRigConfig,
        object: &ObjectConfig,
        seed: u64,
        trial: u32,
        clock: Arc<dyn Clock>,
    ) -> SimDevices {
        let world = Arc::new(Mutex::new(SimWorld::new(cfg, object, seed, trial)));
        let slot = Arc::new(Mutex::new(None));
        let hand = match SimGripper::on_world(world.clone()) {
            Some(gripper) => SimActuator::Gripper(gripper),
            None => SimActuator::Fingers(SimHand {
                world: world.clone(),
                max_volts: cfg.max_volts,
                release_volts: -0.3 * cfg.max_volts,
            }),
        };
        SimDevices {
            tactile: SimTactile {
                world: world.clone(),
                clock,
                period_ns: 1e9 / cfg.tactile_rate_hz,
                rate_hz: cfg.tactile_rate_hz,
                patch: cfg.tactile.patch,
                hand: cfg.hand,
                sequence: 0,
                truth: slot.clone(),
                reference_forces: cfg.reference_forces,
            },
            hand,
            truth: SimTruthTap { slot },
            world,
        }
    }

    /// A reader of the simulated hand's finger positions (and the gripper's status).
    pub fn hand_monitor(&self) -> SimHandMonitor {
        SimHandMonitor::new(self.world.clone())
    }

    /// A gripper and its monitor on this trial's world, for a gripper
    /// emulator to serve; `None` when the hand is not a gripper.
    pub fn gripper_pair(&self) -> Option<(SimGripper, SimHandMonitor)> {
        Some((SimGripper::on_world(self.world.clone())?, self.hand_monitor()))
    }
}

/// The simulated hand of either kind.
pub enum SimActuator {
    /// The three voltage-driven fingers.
    Fingers(SimHand),
    /// The parallel gripper.
    Gripper(SimGripper),
}

impl SimActuator {
    fn inner(&self) -> &dyn HandActuator {
        match self {
            SimActuator::Fingers(h) => h,
            SimActuator::Gripper(g) => g,
        }
    }

    fn inner_mut(&mut self) -> &mut dyn HandActuator {
        match self {
            SimActuator::Fingers(h) => h,
            SimActuator::Gripper(g) => g,
        }
    }
}

impl HandActuator for SimActuator {
    fn spec(&self) -> ActuatorSpec {
        self.inner().spec()
    }

    fn command(&mut self, command: &ActuatorCommand) -> Result<(), DeviceError> {
        self.inner_mut().command(command)
    }

    fn release(&mut self) -> Result<(), DeviceError> {
        self.inner_mut().release()
    }

    fn device(&self) -> &str {
        self.inner().device()
    }
}

/// Reads the simulated fingers' travel, as a hand reporting its joints
/// would; on a gripper, the pads' travel, the opening and the status registers.
pub struct SimHandMonitor {
    world: SharedWorld,
    /// Simulation time of the last status returned.
    last: Option<TimeNs>,
}

impl SimHandMonitor {
    /// A monitor of the hand of `world`.
    pub fn new(world: SharedWorld) -> SimHandMonitor {
        SimHandMonitor { world, last: None }
    }
}

impl HandMonitor for SimHandMonitor {
    fn status(&mut self) -> Result<Option<HandStatus>, DeviceError> {
        let world = lock(&self.world, "sim hand")?;
        let t = world.now();
        if self.last == Some(t) {
            return Ok(None);
        }
        self.last = Some(t);
        let travel = world.finger_travel_m();
        Ok(Some(match world.gripper_status() {
            Some((gripper, opening_m)) => HandStatus {
                t,
                finger_travel_m: travel[..2].to_vec(),
                opening_m: Some(opening_m),
                gripper: Some(gripper),
            },
            None => HandStatus { t, finger_travel_m: travel.to_vec(), opening_m: None, gripper: None },
        }))
    }

    fn device(&self) -> &str {
        "sim hand"
    }
}

/// The simulated tactile modules.
pub struct SimTactile {
    world: SharedWorld,
    clock: Arc<dyn Clock>,
    period_ns: f64,
    rate_hz: f64,
    patch: Option<PatchConfig>,
    hand: HandKind,
    sequence: u64,
    truth: Arc<Mutex<Option<SimTruth>>>,
    /// Attach each taxel's force to every scan (`[sim] reference_forces`).
    reference_forces: bool,
}

/// What the simulated tactile source is: the thesis's single module per
/// finger (the controller and the `finger.axis` channels read it), or a
/// patch per fingertip (named after its finger; readings are patch means).
///
/// On a gripper (`hand = HandKind::Gripper`) there are two sensors, `left`
/// on the `thumb` and `right` on the `index` (one taxel each, or a patch).
/// Per-finger readings stay three: `thumb` reads `left`, `index` reads
/// `right`, and `middle` repeats `right` (the gripper has no third finger;
/// a controller of a gripper uses thumb and index only).
pub fn sim_tactile_info(patch: Option<&PatchConfig>, rate_hz: f64, hand: HandKind) -> TactileInfo {
    let (model, rows, cols) = patch.map_or(("sim", 1, 1), |p| ("sim-patch", p.rows, p.cols));
    let sensor = |name: &str, finger: Finger| SensorLayout {
        taxel_positions_mm: patch.map(PatchConfig::taxel_positions_mm),
        ..SensorLayout::grid(name, model, finger.name(), rows, cols)
    };
    let reading = |name: &str| match patch {
        Some(_) => FingerReading::mean(name),
        None => FingerReading::taxel(name, 0),
    };
    let (sensors, fingers) = match hand {
        HandKind::ThreeFinger if patch.is_none() => {
            return TactileInfo::one_module_per_finger("sim", rate_hz, "sim");
        }
        HandKind::ThreeFinger => (
            Finger::ALL.iter().map(|f| sensor(f.name(), *f)).collect(),
            PerFinger::from_fn(|f| reading(f.name())),
        ),
        HandKind::Gripper => (
            vec![sensor("left", Finger::Thumb), sensor("right", Finger::Index)],
            PerFinger::from_array([reading("left"), reading("right"), reading("right")]),
        ),
    };
    TactileInfo { device: "sim".into(), rate_hz, layout: TactileLayout { sensors }, fingers }
}

impl TactileSource for SimTactile {
    fn read(&mut self) -> Result<TactileSample, DeviceError> {
        let sequence = self.sequence + 1;
        let t = TimeNs((sequence as f64 * self.period_ns).round() as u64);
        self.clock.sleep_until(t);
        let mut world = lock(&self.world, "sim tactile")?;
        world.advance_to(t);
        let raw = world.scan_tactile();
        let truth = world.truth();
        let reference_n = self.reference_forces.then(|| world.taxel_forces_n());
        drop(world);
        if let Ok(mut slot) = self.truth.lock() {
            *slot = Some(truth);
        }
        self.sequence = sequence;
        Ok(TactileSample { reference_n, ..TactileSample::new(t, sequence, raw) })
    }

    fn info(&self) -> TactileInfo {
        sim_tactile_info(self.patch.as_ref(), self.rate_hz, self.hand)
    }
}

/// The truth of the newest scan.
pub struct SimTruthTap {
    slot: Arc<Mutex<Option<SimTruth>>>,
}

impl TruthSource for SimTruthTap {
    fn latest(&mut self) -> Option<SimTruth> {
        self.slot.lock().ok().and_then(|mut s| s.take())
    }
}

/// The simulated hand.
pub struct SimHand {
    world: SharedWorld,
    max_volts: f64,
    release_volts: f64,
}

impl HandActuator for SimHand {
    fn spec(&self) -> ActuatorSpec {
        ActuatorSpec::FingerVolts { max_volts: self.max_volts }
    }

    fn command(&mut self, command: &ActuatorCommand) -> Result<(), DeviceError> {
        let ActuatorCommand::FingerVolts(volts) = command else {
            return Err(command.wrong_kind("sim hand", "finger voltages"));
        };
        let v = saturate(*volts, self.max_volts);
        lock(&self.world, "sim hand")?.set_volts(v);
        Ok(())
    }

    fn release(&mut self) -> Result<(), DeviceError> {
        lock(&self.world, "sim hand")?.set_volts([self.release_volts; 3]);
        Ok(())
    }

    fn device(&self) -> &str {
        "sim hand"
    }
}

impl Drop for SimHand {
    fn drop(&mut self) {
        if let Ok(mut w) = self.world.lock() {
            w.set_volts([self.release_volts; 3]);
        }
    }
}
