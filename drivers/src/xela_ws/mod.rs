//! XELA uSkin sensors read through XELA's own server, `xela_server`, which
//! reads the sensors over CAN and serves their data as JSON on a WebSocket
//! (port 5000 by default). See `docs/protocols.md`, "XELA xela_server
//! (WebSocket JSON)", for the messages and the sources of every fact.
//!
//! - [`protocol`] (always built, no I/O): one text message to a
//!   [`XelaEvent`]: the welcome, or a [`XelaScan`] of every sensor (raw x,
//!   y, z counts per taxel, calibrated forces in newtons when the server has
//!   them). Both encodings of the raw counts are read: the comma-separated
//!   hex string and the list of integers. [`XelaDecoder`] counts messages,
//!   malformed ones and gaps in the server's message counter, and checks the
//!   sensors against the rig's [`Expected`].
//! - `backend::client` (feature `devices`, Linux): `XelaWsClient`, a blocking
//!   client with read timeouts and reconnection with exponential backoff. It
//!   deliberately does not implement
//!   [`TactileSource`](slidetrack_core::TactileSource): the rig's tactile
//!   source wraps it.
//! - [`config`]: `[hw.tactile]` with `kind = "xela_ws"` ([`config::XelaWsTactileConfig`]).
//! - `backend::source` (feature `devices`, Linux): `XelaWsTactile`, the rig's
//!   [`TactileSource`](slidetrack_core::TactileSource) over the client;
//!   `backend::emulated`: the same fed by the simulated rig through the emulator
//!   (`url = "emulated"`).
//! - `backend::emulator` (feature `devices`, Linux): `XelaWsEmulator`, a local
//!   WebSocket server replaying messages at their pace, with faults
//!   (disconnections, malformed JSON, counter gaps, wrong models), for tests
//!   without a kit.

pub mod config;
pub mod protocol;

pub use protocol::{
    Expected, ExpectedSensor, MessageGap, WireStyle, XelaCounters, XelaDecoder, XelaError, XelaEvent,
    XelaScan, XelaSensorScan,
};

#[cfg(all(feature = "devices", target_os = "linux"))]
pub mod backend;
