//! SLCAN adapters: a CAN bus on a serial port (`slcan = { port = ... }` of
//! a CAN tactile device), read without `slcand`.
//!
//! - [`config`]: the `slcan` table.
//! - [`protocol`] (no I/O): the ASCII line codec, its decoder and the
//!   adapter's timestamps.
//! - `backend` (feature `devices`, Linux): `SlcanBus`, a
//!   [`CanBus`](crate::can::backend::socketcan::CanBus) on the port;
//!   `backend::emulator`, an adapter on a pseudo-terminal; and
//!   `backend::emulated`, the CAN tactile backend reading it, fed by the
//!   simulated rig (`port = "emulated"`).

pub mod config;
pub mod protocol;

#[cfg(all(feature = "devices", target_os = "linux"))]
pub mod backend;
