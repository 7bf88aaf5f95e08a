//! The simulated devices: each implements its driver trait on a shared
//! [`SimWorld`], advancing it on the session clock.

use std::sync::{Arc, Mutex, MutexGuard};

use slidetrack_core::{
    ActuatorCommand, ActuatorSpec, Clock, DeviceError, ErrorKind, Finger, FingerReading, HandActuator,
    HandMonitor, HandStatus, PerFinger, SensorLayout, SimTruth, TactileInfo, TactileLayout, TactileSample,
    TactileSource, TimeNs, TruthSource, saturate,
};

use super::config::SimRigConfig;
use super::object::ObjectConfig;
use super::tactile_model::PatchConfig;
use super::world::SimWorld;

/// The world shared by the simulated devices of one trial.
pub type SharedWorld = Arc<Mutex<SimWorld>>;

fn lock<'a>(world: &'a SharedWorld, device: &str) -> Result<MutexGuard<'a, SimWorld>, DeviceError> {
    world.lock().map_err(|_| {
        DeviceError::new(ErrorKind::Fault, device, "simulation state poisoned by an earlier panic")
    })
}

/// The simulated devices of one trial.
pub struct SimDevices {
    /// The three fingertip modules.
    pub tactile: SimTactile,
    /// The hand.
    pub hand: SimHand,
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
        SimDevices {
            tactile: SimTactile {
                world: world.clone(),
                clock,
                period_ns: 1e9 / cfg.tactile_rate_hz,
                rate_hz: cfg.tactile_rate_hz,
                patch: cfg.tactile.patch,
                sequence: 0,
                truth: slot.clone(),
            },
            hand: SimHand {
                world: world.clone(),
                max_volts: cfg.max_volts,
                release_volts: -0.3 * cfg.max_volts,
            },
            truth: SimTruthTap { slot },
            world,
        }
    }

    /// A reader of the simulated hand's finger positions.
    pub fn hand_monitor(&self) -> SimHandMonitor {
        SimHandMonitor { world: self.world.clone(), last: None }
    }
}

/// Reads the simulated fingers' travel, as a hand reporting its joints would.
pub struct SimHandMonitor {
    world: SharedWorld,
    /// Simulation time of the last status returned.
    last: Option<TimeNs>,
}

impl HandMonitor for SimHandMonitor {
    fn status(&mut self) -> Result<Option<HandStatus>, DeviceError> {
        let world = lock(&self.world, "sim hand")?;
        let t = world.now();
        if self.last == Some(t) {
            return Ok(None);
        }
        self.last = Some(t);
        Ok(Some(HandStatus {
            t,
            finger_travel_m: world.finger_travel_m().to_vec(),
            opening_m: None,
            gripper: None,
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
    sequence: u64,
    truth: Arc<Mutex<Option<SimTruth>>>,
}

/// What the simulated tactile source is: the thesis's single module per
/// finger (the controller and the `finger.axis` channels read it), or a
/// patch per fingertip (named after its finger; readings are patch means).
pub fn sim_tactile_info(patch: Option<&PatchConfig>, rate_hz: f64) -> TactileInfo {
    let Some(p) = patch else { return TactileInfo::one_module_per_finger("sim", rate_hz, "sim") };
    let sensors = Finger::ALL
        .iter()
        .map(|f| SensorLayout {
            taxel_positions_mm: Some(p.taxel_positions_mm()),
            ..SensorLayout::grid(f.name(), "sim-patch", f.name(), p.rows, p.cols)
        })
        .collect();
    TactileInfo {
        device: "sim".into(),
        rate_hz,
        layout: TactileLayout { sensors },
        fingers: PerFinger::from_fn(|f| FingerReading::mean(f.name())),
    }
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
        drop(world);
        if let Ok(mut slot) = self.truth.lock() {
            *slot = Some(truth);
        }
        self.sequence = sequence;
        Ok(TactileSample::new(t, sequence, raw))
    }

    fn info(&self) -> TactileInfo {
        sim_tactile_info(self.patch.as_ref(), self.rate_hz)
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
