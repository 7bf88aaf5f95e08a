//! The Robotiq 2F-85/2F-140/Hand-E register map: three request registers
//! from `0x03E8` (robot output, gripper input) and three status registers
//! from `0x07D0` (gripper output), each register two bytes, high byte
//! first. Sources: the Robotiq 2F-85/2F-140 instruction manual, sec. 4.4-4.5
//! (registers, fault codes), its copies in `ros-industrial/robotiq`
//! (`baseRobotiq2FGripper.py`: bit positions, `Robotiq2FGripperStatusListener.py`:
//! fault texts) and `howardjchen/robotiq_850` (README: frames); see
//! `docs/protocols.md`.

use slidetrack_core::{GripperObject, GripperRequest, GripperStatus};

/// First request register (robot output / gripper input).
pub const REQUEST_ADDRESS: u16 = 0x03E8;
/// First status register (gripper output / robot input).
pub const STATUS_ADDRESS: u16 = 0x07D0;
/// Registers in each block (six bytes).
pub const REGISTERS: u16 = 3;
/// The motor current of one `gCU` step (mA).
pub const CURRENT_STEP_MA: u32 = 10;

/// The request registers: what the gripper is asked to do.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RobotiqRequest {
    /// `rACT`: activate (0 resets the gripper and clears faults).
    pub activate: bool,
    /// `rGTO`: go to the requested position.
    pub go_to: bool,
    /// `rATR`: automatic release (slow opening; overrides every other request).
    pub auto_release: bool,
    /// `rARD`: automatic release direction (true: opening).
    pub auto_release_open: bool,
    /// `rPR`: position request, 0 open .. 255 closed.
    pub position: u8,
    /// `rSP`: speed, 0 slowest .. 255 fastest.
    pub speed: u8,
    /// `rFR`: force, 0 weakest .. 255 strongest.
    pub force: u8,
}

impl RobotiqRequest {
    /// All zero: `rACT = 0` resets the gripper (the first step of activation).
    pub fn reset() -> RobotiqRequest {
        RobotiqRequest::default()
    }

    /// `rACT = 1` alone: starts the activation.
    pub fn activate() -> RobotiqRequest {
        RobotiqRequest { activate: true, ..RobotiqRequest::default() }
    }

    /// Activated, go to `request` (position clamped to 255).
    pub fn go_to(request: &GripperRequest) -> RobotiqRequest {
        RobotiqRequest {
            activate: true,
            go_to: true,
            position: request.position_steps.min(255) as u8,
            speed: request.speed,
            force: request.force,
            ..RobotiqRequest::default()
        }
    }

    /// The action request byte (byte 0).
    pub fn action_byte(&self) -> u8 {
        u8::from(self.activate)
            | u8::from(self.go_to) << 3
            | u8::from(self.auto_release) << 4
            | u8::from(self.auto_release_open) << 5
    }

    /// The three register values.
    pub fn to_registers(&self) -> [u16; 3] {
        [
            u16::from(self.action_byte()) << 8,
            u16::from(self.position),
            u16::from_be_bytes([self.speed, self.force]),
        ]
    }

    /// From the three register values (reserved bits ignored).
    pub fn from_registers(r: [u16; 3]) -> RobotiqRequest {
        let action = r[0].to_be_bytes()[0];
        let [speed, force] = r[2].to_be_bytes();
        RobotiqRequest {
            activate: action & 0x01 != 0,
            go_to: action & 0x08 != 0,
            auto_release: action & 0x10 != 0,
            auto_release_open: action & 0x20 != 0,
            position: r[1].to_be_bytes()[1],
            speed,
            force,
        }
    }

    /// The gripper request it carries.
    pub fn gripper_request(&self) -> GripperRequest {
        GripperRequest { position_steps: u16::from(self.position), speed: self.speed, force: self.force }
    }
}

/// `gSTA`: where the activation is.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[repr(u8)]
pub enum ActivationState {
    /// Reset, or automatic release (0).
    #[default]
    Reset = 0,
    /// Activation in progress (1).
    Activating = 1,
    /// Not used by the 2F grippers (2).
    Unused = 2,
    /// Activation completed (3).
    Active = 3,
}

impl ActivationState {
    fn from_bits(bits: u8) -> ActivationState {
        match bits & 0b11 {
            0 => ActivationState::Reset,
            1 => ActivationState::Activating,
            2 => ActivationState::Unused,
            _ => ActivationState::Active,
        }
    }
}

/// The status registers: what the gripper reports.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RobotiqStatus {
    /// `gACT`: echo of `rACT`.
    pub activated_bit: bool,
    /// `gGTO`: echo of `rGTO`.
    pub go_to: bool,
    /// `gSTA`.
    pub state: ActivationState,
    /// `gOBJ`.
    pub object: GripperObject,
    /// `gFLT`: the gripper's fault code (low nibble of byte 2).
    pub fault: u8,
    /// `kFLT`: the optional controller's fault code (high nibble of byte 2).
    pub controller_fault: u8,
    /// `gPR`: echo of the position request.
    pub requested: u8,
    /// `gPO`: the fingers' position (0 open .. 255 closed).
    pub position: u8,
    /// `gCU`: motor current, in 10 mA steps.
    pub current: u8,
}

impl RobotiqStatus {
    /// The status byte (byte 0).
    pub fn status_byte(&self) -> u8 {
        u8::from(self.activated_bit)
            | u8::from(self.go_to) << 3
            | (self.state as u8) << 4
            | (self.object as u8) << 6
    }

    /// The three register values.
    pub fn to_registers(&self) -> [u16; 3] {
        let fault = (self.controller_fault & 0x0F) << 4 | (self.fault & 0x0F);
        [
            u16::from(self.status_byte()) << 8,
            u16::from_be_bytes([fault, self.requested]),
            u16::from_be_bytes([self.position, self.current]),
        ]
    }

    /// From the three register values.
    pub fn from_registers(r: [u16; 3]) -> RobotiqStatus {
        let status = r[0].to_be_bytes()[0];
        let [fault, requested] = r[1].to_be_bytes();
        let [position, current] = r[2].to_be_bytes();
        RobotiqStatus {
            activated_bit: status & 0x01 != 0,
            go_to: status & 0x08 != 0,
            state: ActivationState::from_bits(status >> 4),
            object: GripperObject::from_bits(status >> 6),
            fault: fault & 0x0F,
            controller_fault: fault >> 4,
            requested,
            position,
            current,
        }
    }

    /// Activation completed (`gSTA = 3`).
    pub fn is_active(&self) -> bool {
        self.state == ActivationState::Active
    }

    /// As the driver traits report it.
    pub fn gripper_status(&self) -> GripperStatus {
        GripperStatus {
            activated: self.is_active(),
            object: self.object,
            fault: self.fault,
            requested_steps: u16::from(self.requested),
            position_steps: u16::from(self.position),
            current_ma: u32::from(self.current) * CURRENT_STEP_MA,
        }
    }

    /// A message naming the fault, when there is one.
    pub fn fault_message(&self) -> Option<String> {
        let gripper =
            (self.fault != 0).then(|| format!("gFLT {:#04x}: {}", self.fault, fault_text(self.fault)));
        let controller = (self.controller_fault != 0).then(|| {
            format!("kFLT {:#03x}: controller fault (see the controller's manual)", self.controller_fault)
        });
        match (gripper, controller) {
            (None, None) => None,
            (Some(g), None) => Some(g),
            (None, Some(k)) => Some(k),
            (Some(g), Some(k)) => Some(format!("{g}; {k}")),
        }
    }
}

/// What a `gFLT` code means (2F-85/2F-140 manual, sec. 4.5; the same in
/// `ros-industrial/robotiq`'s status listener for the codes it lists).
pub fn fault_text(code: u8) -> &'static str {
    match code {
        0x00 => "no fault",
        0x05 => "priority fault: action delayed, the activation must complete first",
        0x07 => "priority fault: the activation bit must be set before an action",
        0x08 => "minor fault: maximum operating temperature exceeded, wait for cool-down",
        0x09 => "minor fault: no communication during at least 1 second",
        0x0A => "major fault: under minimum operating voltage (reset needed)",
        0x0B => "major fault: automatic release in progress",
        0x0C => "major fault: internal fault, contact Robotiq support (reset needed)",
        0x0D => "major fault: activation fault, check for interference (reset needed)",
        0x0E => "major fault: overcurrent triggered (reset needed)",
        0x0F => "major fault: automatic release completed (reset needed)",
        _ => "unknown fault code (not in the manual's table)",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn requests_and_status_round_trip_through_the_registers() {
        for byte in 0..=255u8 {
            let s = RobotiqStatus::from_registers([u16::from(byte) << 8, 0x5A80, 0x1234]);
            assert_eq!(RobotiqStatus::from_registers(s.to_registers()), s);
        }
        let r =
            RobotiqRequest { go_to: true, position: 200, speed: 7, force: 9, ..RobotiqRequest::activate() };
        assert_eq!(r.to_registers(), [0x0900, 0x00C8, 0x0709]);
        assert_eq!(RobotiqRequest::from_registers(r.to_registers()), r);
    }

    #[test]
    fn every_fault_code_has_a_text_and_unknown_ones_say_so() {
        assert!(fault_text(0x0E).contains("overcurrent"));
        assert!(fault_text(0x03).contains("unknown"));
        let s = RobotiqStatus { fault: 0x0D, controller_fault: 2, ..RobotiqStatus::default() };
        assert_eq!(
            s.fault_message().expect("a fault"),
            "gFLT 0x0d: major fault: activation fault, check for interference (reset needed); \
             kFLT 0x2: controller fault (see the controller's manual)"
        );
    }
}
