//! Tactile boards on CAN (`[hw.tactile] kind = "can"`), on SocketCAN or an
//! SLCAN adapter ([`crate::slcan`]).
//!
//! - [`config`]: the `[hw.tactile]` table.
//! - [`protocol`] (no I/O): CAN frames and the legacy board layout;
//!   [`layout`] any configured layout (id maps, payloads, command frames,
//!   scan modes) and its decoder; [`candump`] can-utils' log format and
//!   [`log`] a captured log decoded into scans (`slidetrack decode`).
//! - `backend` (feature `devices`, Linux): `CanTactile` reads a bus;
//!   `backend::socketcan` is the [`CanBus`](backend::socketcan::CanBus)
//!   seam and SocketCAN behind it.

pub mod candump;
pub mod config;
pub mod layout;
pub mod log;
pub mod protocol;

#[cfg(all(feature = "devices", target_os = "linux"))]
pub mod backend;
