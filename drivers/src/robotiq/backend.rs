//! What opens a port (feature `devices`, Linux): the Modbus link, the
//! driver, the emulator on a pseudo-terminal and the driver in front of it.

pub mod driver;
pub mod emulated;
pub mod emulator;
pub mod link;

pub use driver::{RobotiqGripper, RobotiqMonitor};
pub use emulated::{EmulatedRobotiqGripper, EmulatedRobotiqMonitor};
pub use emulator::{RobotiqEmulator, RobotiqEmulatorOptions};
