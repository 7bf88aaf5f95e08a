#![doc = include_str!("../README.md")]
#![warn(missing_docs)]
//!
//! The real rig's devices: uSkin-style tactile sensors over serial and CAN,
//! XELA's `xela_server`, V4L2 cameras, the hand on CAN and Robotiq grippers.
//!
//! One folder per transport, each with its configuration, its sans-IO
//! protocol (bytes or frames in, frames or typed errors out, counters kept)
//! and, behind the `devices` feature on Linux, its `backend` (which only
//! moves bytes between a device and the decoder and maps failures onto
//! [`ErrorKind`](slidetrack_core::ErrorKind)s through `io_error_kind`) and
//! its emulator:
//!
//! - [`serial`]: uSkin-style modules streaming the serial format; the
//!   emulator streams the simulated rig's scans through a pseudo-terminal.
//! - [`can`]: tactile boards on CAN (any layout: [`can::layout`]), the
//!   SocketCAN bus, candump logs.
//! - [`slcan`]: SLCAN adapters (a CAN bus on a serial port): codec, bus and
//!   the emulated adapter.
//! - [`xela_ws`]: XELA's `xela_server` (WebSocket JSON): decoder, client,
//!   source and a local emulator.
//! - [`can_hand`]: the thesis's hand on CAN.
//! - [`robotiq`]: Robotiq 2F grippers on Modbus RTU and their emulator.
//! - [`v4l2`]: V4L2 cameras, their frame decoding and the RGB-D pairs.
//!
//! Shared: the `[hw]` table ([`config`]) and its tactile device
//! ([`tactile::TactileDevice`], whose methods open, emulate and describe any
//! kind), the configured sensors ([`sensors`]), what emulators share
//! ([`emulated`]) and, with `devices`, what is plugged in (`devices`). The
//! wire formats are in `docs/protocols.md`.

pub mod can;
pub mod can_hand;
pub mod config;
#[cfg(all(feature = "devices", target_os = "linux"))]
pub mod devices;
pub mod emulated;
#[cfg(all(feature = "devices", target_os = "linux"))]
mod io_error_kind;
pub mod robotiq;
pub mod sensors;
pub mod serial;
pub mod slcan;
pub mod tactile;
pub mod v4l2;
pub mod xela_ros2;
pub mod xela_ws;

pub use config::HwRigConfig;
#[cfg(all(feature = "devices", target_os = "linux"))]
pub use v4l2::backend::V4l2Camera;
pub use v4l2::{mjpeg, rgbd_config};
