//! The hand actuator: a hand whose fingers close under a voltage each (the
//! thesis's iCub hand, eq. 6.9) or a position-controlled parallel gripper
//! (Robotiq 2F), behind one trait.

use crate::{DeviceError, ErrorKind, TimeNs};

/// Voltages for the proximal joints, `[thumb, index, middle]` (V).
pub type FingerVolts = [f64; 3];

/// A request to a position-controlled parallel gripper, in the gripper's
/// own resolution (Robotiq: the `rPR`, `rSP` and `rFR` registers).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct GripperRequest {
    /// Closure in position steps: 0 is fully open, [`GripperSpec::max_steps`]
    /// fully closed (Robotiq 2F-85: 0..=255, about 0.33 mm of opening each).
    pub position_steps: u16,
    /// Speed, in steps of the gripper's speed range (0 slowest).
    pub speed: u8,
    /// Force limit, in steps of the gripper's force range (0 weakest).
    pub force: u8,
}

/// What a position-controlled gripper is.
#[derive(Clone, Debug, PartialEq)]
pub struct GripperSpec {
    /// The largest position request (fully closed).
    pub max_steps: u16,
    /// Fingertip opening when fully open (m); fully closed is 0.
    pub stroke_m: f64,
    /// Opening speed at the slowest and the fastest speed request (m/s).
    pub speed_range_mps: (f64, f64),
    /// Grip force at the weakest and the strongest force request (N).
    pub force_range_n: (f64, f64),
}

impl GripperSpec {
    /// The Robotiq 2F-85 as its manual states it: 85 mm stroke, 20-150 mm/s,
    /// 20-235 N, 8-bit position, speed and force requests.
    pub fn robotiq_2f85() -> GripperSpec {
        GripperSpec {
            max_steps: 255,
            stroke_m: 0.085,
            speed_range_mps: (0.02, 0.15),
            force_range_n: (20.0, 235.0),
        }
    }

    /// Opening change per position step (m).
    pub fn step_m(&self) -> f64 {
        self.stroke_m / f64::from(self.max_steps.max(1))
    }

    /// The speed of a speed request (m/s), linear over the range.
    pub fn speed_mps(&self, speed: u8) -> f64 {
        let (lo, hi) = self.speed_range_mps;
        lo + (hi - lo) * f64::from(speed) / 255.0
    }

    /// The force limit of a force request (N), linear over the range.
    pub fn force_n(&self, force: u8) -> f64 {
        let (lo, hi) = self.force_range_n;
        lo + (hi - lo) * f64::from(force) / 255.0
    }
}

/// What an actuator accepts.
#[derive(Clone, Debug, PartialEq)]
pub enum ActuatorSpec {
    /// One proximal-joint voltage per finger, within `±max_volts` (V).
    FingerVolts {
        /// The largest voltage magnitude the hand accepts (V).
        max_volts: f64,
    },
    /// Position requests to a parallel gripper.
    Gripper(GripperSpec),
}

/// A command to a hand, of the kind its [`ActuatorSpec`] accepts.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ActuatorCommand {
    /// Proximal-joint voltages (V), `[thumb, index, middle]`.
    FingerVolts(FingerVolts),
    /// A gripper position request.
    Gripper(GripperRequest),
}

impl ActuatorCommand {
    /// The command a hand of `spec` would execute: voltages saturated to
    /// `±max_volts`, positions clamped to `max_steps`; and whether that
    /// changed it. `None` when the command is of the other kind.
    pub fn limited_to(&self, spec: &ActuatorSpec) -> Option<(ActuatorCommand, bool)> {
        match (self, spec) {
            (ActuatorCommand::FingerVolts(v), ActuatorSpec::FingerVolts { max_volts }) => {
                let s = saturate(*v, *max_volts);
                Some((ActuatorCommand::FingerVolts(s), s != *v))
            }
            (ActuatorCommand::Gripper(r), ActuatorSpec::Gripper(g)) => {
                let clamped = GripperRequest { position_steps: r.position_steps.min(g.max_steps), ..*r };
                Some((ActuatorCommand::Gripper(clamped), clamped != *r))
            }
            _ => None,
        }
    }

    /// The kind of command, for messages.
    pub fn kind(&self) -> &'static str {
        match self {
            ActuatorCommand::FingerVolts(_) => "finger voltages",
            ActuatorCommand::Gripper(_) => "gripper request",
        }
    }

    /// The error a backend returns for a command of the wrong kind.
    pub fn wrong_kind(&self, device: &str, accepts: &str) -> DeviceError {
        DeviceError::new(ErrorKind::Other, device, format!("got {}, accepts {accepts} only", self.kind()))
    }
}

/// A hand that closes on the object: voltage-driven fingers or a gripper.
///
/// # Contract
/// - `spec` says which [`ActuatorCommand`] the backend accepts; a command of
///   the other kind is refused with an error, never sent.
/// - `command` sends one command and returns at once, never waiting for the
///   hand to move. Voltages beyond `±max_volts` are saturated and gripper
///   positions beyond `max_steps` clamped by the backend (never sent as they
///   are). A positive voltage, or a larger position, closes the hand.
/// - `release` opens the hand safely (fingers away from the object, then
///   zero voltage; a gripper fully open) and must be callable at any time,
///   repeatedly, also after an error. Backends call it themselves when dropped.
/// - Errors: [`crate::ErrorKind::Disconnected`] when the hand is gone,
///   [`crate::ErrorKind::Fault`] when it reports a fault of its own.
pub trait HandActuator: Send {
    /// What the hand accepts.
    fn spec(&self) -> ActuatorSpec;
    /// Sends one command.
    fn command(&mut self, command: &ActuatorCommand) -> Result<(), DeviceError>;
    /// Opens the hand safely.
    fn release(&mut self) -> Result<(), DeviceError>;
    /// Name of the device, for messages.
    fn device(&self) -> &str;
}

/// Clamps each voltage to `±max_volts`; NaN becomes 0 (never sent to a motor).
pub fn saturate(volts: FingerVolts, max_volts: f64) -> FingerVolts {
    volts.map(|v| if v.is_nan() { 0.0 } else { v.clamp(-max_volts, max_volts) })
}

/// What a hand reports about itself: whatever part of it the device can
/// tell without being commanded.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct HandStatus {
    /// When the status was read, on the session clock.
    pub t: TimeNs,
    /// Each finger's travel from its open rest position towards the object
    /// (m), in the hand's finger order; empty when the hand does not report it.
    pub finger_travel_m: Vec<f64>,
    /// Opening between the fingertips (m), for grippers that report it.
    pub opening_m: Option<f64>,
    /// A gripper's own status registers, for grippers that report them.
    pub gripper: Option<GripperStatus>,
}

/// What a gripper's fingers are doing (Robotiq `gOBJ`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[repr(u8)]
pub enum GripperObject {
    /// Moving towards the requested position, no object detected (`gOBJ = 0`).
    #[default]
    Moving = 0,
    /// Stopped by a contact while opening (`gOBJ = 1`).
    ContactOpening = 1,
    /// Stopped by a contact while closing: an object is held (`gOBJ = 2`).
    ContactClosing = 2,
    /// At the requested position with no object: none there, or it was lost (`gOBJ = 3`).
    AtRequest = 3,
}

impl GripperObject {
    /// From the `gOBJ` field (two bits; higher bits ignored).
    pub fn from_bits(bits: u8) -> GripperObject {
        match bits & 0b11 {
            0 => GripperObject::Moving,
            1 => GripperObject::ContactOpening,
            2 => GripperObject::ContactClosing,
            _ => GripperObject::AtRequest,
        }
    }
}

/// A gripper's status as it reports it (Robotiq: the registers from `0x07D0`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct GripperStatus {
    /// Activated and ready (`gSTA = 3`).
    pub activated: bool,
    /// Object detection (`gOBJ`).
    pub object: GripperObject,
    /// The fault code (`gFLT`), 0 when none.
    pub fault: u8,
    /// The position request it is following (`gPR`), in position steps.
    pub requested_steps: u16,
    /// The fingers' position (`gPO`), in position steps (0 = open).
    pub position_steps: u16,
    /// Motor current (mA; Robotiq `gCU` is in 10 mA units).
    pub current_ma: u32,
}

/// Reads a hand's status without commanding it (`slidetrack record`, which
/// records a hand that something else drives).
///
/// # Contract
/// - `status` returns at once: the latest status, or `None` when nothing
///   new is known since the previous call.
/// - Errors: [`crate::ErrorKind::Disconnected`] when the hand is gone.
pub trait HandMonitor: Send {
    /// The latest status, if there is a new one.
    fn status(&mut self) -> Result<Option<HandStatus>, DeviceError>;
    /// Name of the device, for messages.
    fn device(&self) -> &str;
}
