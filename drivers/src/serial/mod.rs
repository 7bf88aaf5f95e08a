//! uSkin-style tactile modules streaming the serial format
//! (`[hw.tactile] kind = "serial"`).
//!
//! - [`config`]: the `[hw.tactile]` table.
//! - [`protocol`] (no I/O): module frames, their encoder and the
//!   resynchronising decoder; [`scan`] joins one scan's frames; [`capture`]
//!   decodes a captured byte stream (`slidetrack decode`).
//! - `backend` (feature `devices`, Linux): `SerialTactile` reads a port;
//!   `backend::emulator` streams the simulated rig's scans into a
//!   pseudo-terminal (`port = "emulated"`), with faults.

pub mod capture;
pub mod config;
pub mod protocol;
pub mod scan;

#[cfg(all(feature = "devices", target_os = "linux"))]
pub mod backend;
