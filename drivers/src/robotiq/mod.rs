//! Robotiq 2F-85, 2F-140 and Hand-E grippers on Modbus RTU (RS-485,
//! 115200 baud 8N1, device id 9 by default).
//!
//! [`modbus`] frames requests and responses without I/O, [`registers`]
//! maps the request and status registers onto the driver traits' types,
//! [`server`] is the gripper's side of the protocol (activation, `gOBJ`,
//! faults) in front of any actuator and monitor, [`model`] a kinematic
//! gripper to put behind it. With the `devices` feature, in `backend`: `link` runs
//! transactions on a serial port, `driver` is the `RobotiqGripper`
//! (a `HandActuator` and, through `RobotiqGripper::monitor`, a
//! `HandMonitor`), `emulator` serves a gripper on a pseudo-terminal and
//! `emulated` puts the driver in front of it (`port = "emulated"`).
//! The protocol and its sources are in `docs/protocols.md`.

pub mod config;
pub mod modbus;
pub mod model;
pub mod registers;
pub mod server;

pub use config::{RobotiqConfig, RobotiqModel};
pub use model::{KinematicActuator, KinematicMonitor, kinematic_gripper};

#[cfg(all(feature = "devices", target_os = "linux"))]
pub mod backend;
