//! uSkin-style tactile modules on a serial port. The port only moves bytes
//! into a [`SerialDecoder`](crate::serial::protocol::SerialDecoder); module frames become fingertip scans through a
//! [`ModuleScanAssembler`](crate::serial::scan::ModuleScanAssembler).

mod device;
pub mod emulator;

pub use device::SerialTactile;
pub use emulator::{EmulatedPort, EmulatedSerialTactile, SerialEmulator};
