//! The simulated parallel gripper as a device: position requests in, the
//! Robotiq-style status out, on a shared [`SimWorld`](super::SimWorld).

use slidetrack_core::{
    ActuatorCommand, ActuatorSpec, DeviceError, ErrorKind, GripperRequest, GripperSpec, GripperStatus,
    HandActuator,
};

use super::shared_world::{SharedWorld, lock};

const DEVICE: &str = "sim gripper";

/// The simulated gripper: takes [`ActuatorCommand::Gripper`] requests (only
/// whole position steps exist), releases by opening fully at full speed.
///
/// With [`crate::SimHandMonitor`] on the same world it is what a gripper
/// emulator (a Robotiq Modbus server) serves: requests in through
/// [`HandActuator::command`], status registers out through
/// [`SimGripper::status`] or the monitor.
pub struct SimGripper {
    world: SharedWorld,
    spec: GripperSpec,
    /// Force of the last request, kept by a release.
    force: u8,
}

impl SimGripper {
    /// The gripper of `world`; `None` when the world's hand is not a gripper.
    pub fn on_world(world: SharedWorld) -> Option<SimGripper> {
        let spec = {
            let w = world.lock().ok()?;
            w.gripper()?;
            w.config().gripper.spec()
        };
        Some(SimGripper { world, spec, force: 0 })
    }

    /// The status registers now (Robotiq `gSTA`, `gOBJ`, `gFLT`, `gPR`,
    /// `gPO`, `gCU`) and the opening between the pads (m).
    pub fn status(&self) -> Result<(GripperStatus, f64), DeviceError> {
        lock(&self.world, DEVICE)?
            .gripper_status()
            .ok_or_else(|| DeviceError::new(ErrorKind::Fault, DEVICE, "the simulated hand is not a gripper"))
    }

    fn send(&mut self, request: GripperRequest) -> Result<(), DeviceError> {
        self.force = request.force;
        lock(&self.world, DEVICE)?.command_gripper(request);
        Ok(())
    }
}

impl HandActuator for SimGripper {
    fn spec(&self) -> ActuatorSpec {
        ActuatorSpec::Gripper(self.spec.clone())
    }

    fn command(&mut self, command: &ActuatorCommand) -> Result<(), DeviceError> {
        let ActuatorCommand::Gripper(request) = command else {
            return Err(command.wrong_kind(DEVICE, "gripper requests"));
        };
        let clamped = request.position_steps.min(self.spec.max_steps);
        self.send(GripperRequest { position_steps: clamped, ..*request })
    }

    fn release(&mut self) -> Result<(), DeviceError> {
        self.send(GripperRequest { position_steps: 0, speed: u8::MAX, force: self.force })
    }

    fn device(&self) -> &str {
        DEVICE
    }
}

impl Drop for SimGripper {
    fn drop(&mut self) {
        let _ = self.release();
    }
}
