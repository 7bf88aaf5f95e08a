//! The thesis's hand on CAN (`[hw.hand] kind = "can"`): proximal-joint
//! voltage set-points, a heartbeat and a release frame.
//!
//! - [`config`]: the `[hw.hand]` table.
//! - [`protocol`] (no I/O): the hand's frames.
//! - `backend` (feature `devices`, Linux): `CanHand`, the actuator on SocketCAN.

pub mod config;
pub mod protocol;

#[cfg(all(feature = "devices", target_os = "linux"))]
pub mod backend;
