#![doc = include_str!("../README.md")]
#![warn(missing_docs)]
//!
//! The real rig's devices: uSkin-style tactile sensors over serial and CAN,
//! V4L2 cameras and the hand actuator on CAN.
//!
//! Protocols are decoded without I/O ([`serial_protocol`], [`can_protocol`],
//! [`hand_can`]: bytes or frames in, frames or typed errors out, counters
//! kept; [`can_layout`] for any CAN tactile layout); the backends ([`serial`], [`can`],
//! [`can_tactile`], [`slcan_bus`], [`can_hand`], [`v4l2`]) only
//! move bytes between a device and a decoder and map failures onto
//! [`ErrorKind`](slidetrack_core::ErrorKind)s. The wire formats are documented in `docs/protocols.md`.
//! [`emulator`] streams the simulated rig's tactile data as real serial
//! bytes through a pseudo-terminal, [`can_emulator`] as SLCAN lines of an
//! emulated USB-CAN adapter; [`offline`] decodes captured traffic.
//! [`xela_ws`] reads XELA's `xela_server` (WebSocket JSON): its decoder, a
//! blocking client and a local emulator. [`robotiq`] drives Robotiq 2F
//! grippers over Modbus RTU and emulates one on a pseudo-terminal.

#[cfg(all(feature = "devices", target_os = "linux"))]
pub mod can;
pub mod can_config;
#[cfg(all(feature = "devices", target_os = "linux"))]
pub mod can_emulator;
#[cfg(all(feature = "devices", target_os = "linux"))]
pub mod can_hand;
pub mod can_layout;
pub mod can_protocol;
#[cfg(all(feature = "devices", target_os = "linux"))]
pub mod can_tactile;
pub mod candump;
pub mod config;
#[cfg(all(feature = "devices", target_os = "linux"))]
pub mod devices;
#[cfg(all(feature = "devices", target_os = "linux"))]
pub mod emulator;
pub mod hand_can;
pub mod mjpeg;
pub mod offline;
pub mod rgbd_config;
pub mod robotiq;
pub mod scan;
pub mod sensors;
#[cfg(all(feature = "devices", target_os = "linux"))]
pub mod serial;
pub mod serial_protocol;
pub mod slcan;
#[cfg(all(feature = "devices", target_os = "linux"))]
pub mod slcan_bus;
#[cfg(all(feature = "devices", target_os = "linux"))]
pub mod slcan_emulator;
#[cfg(all(feature = "devices", target_os = "linux"))]
pub mod v4l2;
pub mod v4l2_decode;
pub mod xela_ws;

#[cfg(all(feature = "devices", target_os = "linux"))]
pub use can::{CanBus, SocketCanBus};
#[cfg(all(feature = "devices", target_os = "linux"))]
pub use can_emulator::EmulatedSlcanTactile;
#[cfg(all(feature = "devices", target_os = "linux"))]
pub use can_hand::CanHand;
#[cfg(all(feature = "devices", target_os = "linux"))]
pub use can_tactile::CanTactile;
pub use config::HwRigConfig;
#[cfg(all(feature = "devices", target_os = "linux"))]
pub use emulator::{EmulatedPort, EmulatedSerialTactile, SerialEmulator};
#[cfg(all(feature = "devices", target_os = "linux"))]
pub use serial::SerialTactile;
#[cfg(all(feature = "devices", target_os = "linux"))]
pub use slcan_bus::SlcanBus;
#[cfg(all(feature = "devices", target_os = "linux"))]
pub use slcan_emulator::SlcanEmulator;
#[cfg(all(feature = "devices", target_os = "linux"))]
pub use v4l2::V4l2Camera;

#[cfg(all(feature = "devices", target_os = "linux"))]
use nix::errno::Errno;

#[cfg(all(feature = "devices", target_os = "linux"))]
use slidetrack_core::ErrorKind;

#[cfg(all(feature = "devices", target_os = "linux"))]
/// The [`ErrorKind`] of an I/O error from a device: a vanished device
/// (hang-up, `ENODEV`, `EIO`, interface down) is `Disconnected`.
pub(crate) fn io_error_kind(e: &std::io::Error) -> ErrorKind {
    use std::io::ErrorKind as K;
    if let Some(code) = e.raw_os_error() {
        let errno = Errno::from_raw(code);
        match errno {
            Errno::ENODEV | Errno::ENXIO | Errno::EIO | Errno::ENETDOWN | Errno::EPIPE | Errno::EBADF => {
                return ErrorKind::Disconnected;
            }
            Errno::ENOBUFS => return ErrorKind::Overrun,
            Errno::ETIMEDOUT | Errno::EAGAIN => return ErrorKind::Timeout,
            _ => {}
        }
    }
    match e.kind() {
        K::TimedOut | K::WouldBlock => ErrorKind::Timeout,
        K::BrokenPipe
        | K::NotFound
        | K::UnexpectedEof
        | K::ConnectionReset
        | K::ConnectionAborted
        | K::NotConnected => ErrorKind::Disconnected,
        // serialport reports a failed read(2) on a vanished USB device as
        // an untyped error carrying the errno's text.
        _ if e.to_string().contains("I/O error") || e.to_string().contains("No such device") => {
            ErrorKind::Disconnected
        }
        _ => ErrorKind::Other,
    }
}

#[cfg(all(test, feature = "devices", target_os = "linux"))]
mod tests {
    use super::*;

    #[test]
    fn vanished_devices_are_disconnected() {
        let kind = |e: std::io::Error| io_error_kind(&e);
        assert_eq!(kind(std::io::Error::from_raw_os_error(Errno::ENODEV as i32)), ErrorKind::Disconnected);
        assert_eq!(kind(std::io::Error::from_raw_os_error(Errno::ENETDOWN as i32)), ErrorKind::Disconnected);
        assert_eq!(kind(std::io::ErrorKind::BrokenPipe.into()), ErrorKind::Disconnected);
        assert_eq!(kind(std::io::Error::other("I/O error")), ErrorKind::Disconnected);
        assert_eq!(kind(std::io::ErrorKind::TimedOut.into()), ErrorKind::Timeout);
        assert_eq!(kind(std::io::Error::from_raw_os_error(Errno::ENOBUFS as i32)), ErrorKind::Overrun);
        assert_eq!(kind(std::io::ErrorKind::InvalidInput.into()), ErrorKind::Other);
    }
}
