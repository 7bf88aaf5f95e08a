//! `port = "emulated"`: the driver on the device side of an emulator's
//! pseudo-terminal, so that the whole Modbus path runs without a gripper.
//! Until the simulated gripper is plugged in (see
//! [`RobotiqEmulator::start`]), the kinematic model stands behind it.

use std::sync::Arc;

use slidetrack_core::{
    ActuatorCommand, ActuatorSpec, Clock, DeviceError, HandActuator, HandMonitor, HandStatus,
};

use super::driver::{RobotiqGripper, RobotiqMonitor};
use super::emulator::{RobotiqEmulator, RobotiqEmulatorOptions};
use crate::robotiq::config::RobotiqConfig;

fn start_emulator(cfg: &RobotiqConfig) -> Result<(RobotiqEmulator, RobotiqConfig), DeviceError> {
    let width_m = cfg.emulator.object_width_mm.map(|w| w / 1000.0);
    let emulator = RobotiqEmulator::kinematic(cfg.model, width_m, RobotiqEmulatorOptions::from_config(cfg))?;
    let on_pty = RobotiqConfig { port: emulator.path().to_string(), ..cfg.clone() };
    Ok((emulator, on_pty))
}

/// The driver driving the emulated gripper of `cfg.emulator`. Dropping it
/// releases the gripper, then stops the emulator.
pub struct EmulatedRobotiqGripper {
    gripper: RobotiqGripper,
    _emulator: RobotiqEmulator,
}

impl EmulatedRobotiqGripper {
    /// Starts the emulator, then opens (and activates) it with `cfg`.
    pub fn start(cfg: &RobotiqConfig, clock: Arc<dyn Clock>) -> Result<EmulatedRobotiqGripper, DeviceError> {
        let (emulator, on_pty) = start_emulator(cfg)?;
        Ok(EmulatedRobotiqGripper { gripper: RobotiqGripper::open(&on_pty, clock)?, _emulator: emulator })
    }

    /// Starts the emulator serving `actuator` and `monitor` (the simulated
    /// gripper, so that emulated sensors feel what it does), then opens (and
    /// activates) it with `cfg`.
    pub fn serving(
        actuator: Box<dyn HandActuator>,
        monitor: Box<dyn HandMonitor>,
        cfg: &RobotiqConfig,
        clock: Arc<dyn Clock>,
    ) -> Result<EmulatedRobotiqGripper, DeviceError> {
        let emulator = RobotiqEmulator::start(actuator, monitor, RobotiqEmulatorOptions::from_config(cfg))?;
        let on_pty = RobotiqConfig { port: emulator.path().to_string(), ..cfg.clone() };
        Ok(EmulatedRobotiqGripper { gripper: RobotiqGripper::open(&on_pty, clock)?, _emulator: emulator })
    }

    /// The driver's monitor.
    pub fn monitor(&self) -> RobotiqMonitor {
        self.gripper.monitor()
    }
}

impl HandActuator for EmulatedRobotiqGripper {
    fn spec(&self) -> ActuatorSpec {
        self.gripper.spec()
    }

    /// As [`RobotiqGripper`]'s: the requests go through a real tty.
    fn command(&mut self, command: &ActuatorCommand) -> Result<(), DeviceError> {
        self.gripper.command(command)
    }

    fn release(&mut self) -> Result<(), DeviceError> {
        self.gripper.release()
    }

    fn device(&self) -> &str {
        self.gripper.device()
    }
}

/// The driver watching the emulated gripper (no activation, no commands).
pub struct EmulatedRobotiqMonitor {
    monitor: RobotiqMonitor,
    _emulator: RobotiqEmulator,
}

impl EmulatedRobotiqMonitor {
    /// Starts the emulator, then watches it with `cfg`.
    pub fn start(cfg: &RobotiqConfig, clock: Arc<dyn Clock>) -> Result<EmulatedRobotiqMonitor, DeviceError> {
        let (emulator, on_pty) = start_emulator(cfg)?;
        Ok(EmulatedRobotiqMonitor { monitor: RobotiqMonitor::watch(&on_pty, clock)?, _emulator: emulator })
    }
}

impl HandMonitor for EmulatedRobotiqMonitor {
    fn status(&mut self) -> Result<Option<HandStatus>, DeviceError> {
        self.monitor.status()
    }

    fn device(&self) -> &str {
        self.monitor.device()
    }
}
