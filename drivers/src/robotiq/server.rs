//! The gripper's side of the protocol, without I/O: request registers in,
//! status registers out, the activation state machine, `gOBJ`, faults. It
//! drives any [`HandActuator`] (the fingers) and reads any [`HandMonitor`]
//! (their position, object detection and current), so that the emulator
//! can stand in front of the kinematic model or the simulated gripper.

use std::time::{Duration, Instant};

use slidetrack_core::{ActuatorCommand, GripperObject, GripperStatus, HandActuator, HandMonitor};

use super::modbus::{MAX_READ, Request, Response, exception};
use super::registers::{
    ActivationState, CURRENT_STEP_MA, REGISTERS, REQUEST_ADDRESS, RobotiqRequest, RobotiqStatus,
    STATUS_ADDRESS,
};

/// `gFLT` while an automatic release runs, and once it has completed.
const AUTO_RELEASE_RUNNING: u8 = 0x0B;
const AUTO_RELEASE_DONE: u8 = 0x0F;
/// `gFLT` for a motion requested during the activation, and before it.
const ACTION_DELAYED: u8 = 0x05;
const NOT_ACTIVATED: u8 = 0x07;
/// `gFLT` codes from here on are major faults: the fingers stop obeying.
const FIRST_MAJOR_FAULT: u8 = 0x0A;

/// The activation as the server tracks it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Activation {
    Reset,
    Activating { since: Instant },
    Active { since: Instant },
}

/// What the server has done, for tests and the log.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ServerRecord {
    /// The request registers as last written.
    pub request: RobotiqRequest,
    /// Writes to the request registers.
    pub request_writes: u64,
    /// Requests passed to the actuator.
    pub commands: u64,
    /// The last request passed to the actuator.
    pub last_command: Option<slidetrack_core::GripperRequest>,
    /// Releases passed to the actuator (automatic release, `rATR`).
    pub releases: u64,
    /// Activations completed.
    pub activations: u64,
    /// Requests refused with an exception (or silence, see `exceptions`).
    pub refused: u64,
}

/// The register state machine of one gripper.
pub struct GripperServer {
    actuator: Box<dyn HandActuator>,
    monitor: Box<dyn HandMonitor>,
    activation_time: Duration,
    activation: Activation,
    fault: u8,
    /// The request last passed to the actuator.
    forwarded: Option<RobotiqRequest>,
    fingers: GripperStatus,
    record: ServerRecord,
}

impl GripperServer {
    /// A gripper in reset whose activation takes `activation_time`.
    pub fn new(
        actuator: Box<dyn HandActuator>,
        monitor: Box<dyn HandMonitor>,
        activation_time: Duration,
    ) -> Self {
        GripperServer {
            actuator,
            monitor,
            activation_time,
            activation: Activation::Reset,
            fault: 0,
            forwarded: None,
            fingers: GripperStatus::default(),
            record: ServerRecord::default(),
        }
    }

    /// What it has done so far.
    pub fn record(&self) -> ServerRecord {
        self.record
    }

    /// When the activation completed, if it has.
    pub fn active_since(&self) -> Option<Instant> {
        match self.activation {
            Activation::Active { since } => Some(since),
            _ => None,
        }
    }

    /// Reports `code` as `gFLT` from now on (a major fault stops the
    /// fingers obeying until a reset).
    pub fn inject_fault(&mut self, code: u8) {
        self.fault = code & 0x0F;
    }

    /// Moves time on to `now`: completes the activation when it is due.
    pub fn tick(&mut self, now: Instant) {
        if let Activation::Activating { since } = self.activation
            && now.duration_since(since) >= self.activation_time
        {
            self.activation = Activation::Active { since: now };
            self.record.activations += 1;
            if self.fault == ACTION_DELAYED {
                self.fault = 0;
            }
            self.forward();
        }
        if self.fault == AUTO_RELEASE_RUNNING && self.fingers.position_steps == 0 {
            self.fault = AUTO_RELEASE_DONE;
        }
    }

    /// The answer to `request` at `now`: a response, or `Err(code)` for an
    /// exception.
    pub fn answer(&mut self, request: &Request, now: Instant) -> Result<Response, u8> {
        self.tick(now);
        match request {
            Request::ReadHolding { address, count } | Request::ReadInput { address, count } => {
                self.read(*address, *count).map(Response::Registers)
            }
            Request::WriteSingle { address, value } => {
                self.write(*address, &[*value], now)?;
                Ok(Response::WroteSingle { address: *address, value: *value })
            }
            Request::WriteMultiple { address, values } => {
                self.write(*address, values, now)?;
                Ok(Response::WroteMultiple { address: *address, count: values.len() as u16 })
            }
            Request::ReadWriteMultiple { read_address, read_count, write_address, values } => {
                // Both ranges are checked before the write happens.
                self.read(*read_address, *read_count)?;
                self.write(*write_address, values, now)?;
                self.read(*read_address, *read_count).map(Response::Registers)
            }
        }
        .inspect_err(|_| self.record.refused += 1)
    }

    /// The registers `address..address + count` of the status block (or,
    /// read back, of the request block).
    fn read(&mut self, address: u16, count: u16) -> Result<Vec<u16>, u8> {
        if count == 0 || count > MAX_READ {
            return Err(exception::ILLEGAL_DATA_VALUE);
        }
        let block = if in_block(address, count, STATUS_ADDRESS) {
            self.status().to_registers()
        } else if in_block(address, count, REQUEST_ADDRESS) {
            self.record.request.to_registers()
        } else {
            return Err(exception::ILLEGAL_DATA_ADDRESS);
        };
        let first =
            usize::from(address - if address >= STATUS_ADDRESS { STATUS_ADDRESS } else { REQUEST_ADDRESS });
        Ok(block[first..first + usize::from(count)].to_vec())
    }

    fn write(&mut self, address: u16, values: &[u16], now: Instant) -> Result<(), u8> {
        let count = values.len() as u16;
        if count == 0 || !in_block(address, count, REQUEST_ADDRESS) {
            return Err(exception::ILLEGAL_DATA_ADDRESS);
        }
        let mut registers = self.record.request.to_registers();
        let first = usize::from(address - REQUEST_ADDRESS);
        registers[first..first + values.len()].copy_from_slice(values);
        self.on_request(RobotiqRequest::from_registers(registers), now);
        Ok(())
    }

    /// The gripper's reaction to new request registers.
    fn on_request(&mut self, new: RobotiqRequest, now: Instant) {
        let old = std::mem::replace(&mut self.record.request, new);
        self.record.request_writes += 1;
        if !new.activate {
            // rACT = 0: reset, faults cleared.
            self.activation = Activation::Reset;
            self.fault = 0;
            self.forwarded = None;
            return;
        }
        if !old.activate {
            self.activation = Activation::Activating { since: now };
            self.fault = 0;
        }
        let active = matches!(self.activation, Activation::Active { .. });
        if new.auto_release && !old.auto_release {
            match self.actuator.release() {
                Ok(()) => self.record.releases += 1,
                Err(e) => tracing::warn!("robotiq emulator: {e}"),
            }
            self.fault = AUTO_RELEASE_RUNNING;
            return;
        }
        if new.go_to && !active && self.fault < FIRST_MAJOR_FAULT {
            self.fault = if matches!(self.activation, Activation::Activating { .. }) {
                ACTION_DELAYED
            } else {
                NOT_ACTIVATED
            };
        }
        self.forward();
    }

    /// Passes the request registers to the actuator when they ask for a
    /// motion the gripper can make and it has not been passed yet.
    fn forward(&mut self) {
        let r = self.record.request;
        let active = matches!(self.activation, Activation::Active { .. });
        if !active
            || !r.go_to
            || r.auto_release
            || self.fault >= FIRST_MAJOR_FAULT
            || self.forwarded == Some(r)
        {
            return;
        }
        self.forwarded = Some(r);
        if self.fault == NOT_ACTIVATED || self.fault == ACTION_DELAYED {
            self.fault = 0;
        }
        match self.actuator.command(&ActuatorCommand::Gripper(r.gripper_request())) {
            Ok(()) => {
                self.record.commands += 1;
                self.record.last_command = Some(r.gripper_request());
            }
            Err(e) => tracing::warn!("robotiq emulator: {e}"),
        }
    }

    /// The status registers now: the activation and faults of this state
    /// machine, the fingers as the monitor reports them.
    pub fn status(&mut self) -> RobotiqStatus {
        match self.monitor.status() {
            Ok(Some(s)) => {
                if let Some(g) = s.gripper {
                    self.fingers = g;
                }
            }
            Ok(None) => {}
            Err(e) => tracing::debug!("robotiq emulator: {e}"),
        }
        let r = self.record.request;
        let state = match self.activation {
            Activation::Reset => ActivationState::Reset,
            Activation::Activating { .. } => ActivationState::Activating,
            Activation::Active { .. } => ActivationState::Active,
        };
        let moving_to_request = state == ActivationState::Active && r.go_to;
        RobotiqStatus {
            activated_bit: r.activate,
            go_to: r.go_to,
            state,
            object: if moving_to_request { self.fingers.object } else { GripperObject::Moving },
            fault: self.fault,
            controller_fault: 0,
            requested: if r.activate { r.position } else { 0 },
            position: self.fingers.position_steps.min(255) as u8,
            current: (self.fingers.current_ma / CURRENT_STEP_MA).min(255) as u8,
        }
    }
}

/// Whether `address..address + count` lies within the block at `first`.
fn in_block(address: u16, count: u16, first: u16) -> bool {
    address >= first && u32::from(address) + u32::from(count) <= u32::from(first) + u32::from(REGISTERS)
}
