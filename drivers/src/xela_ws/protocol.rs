//! The JSON messages XELA's `xela_server` sends on its WebSocket, decoded
//! without I/O (see `docs/protocols.md`, "XELA xela_server (WebSocket JSON)").
//!
//! Every WebSocket text message is one JSON object:
//!
//! - the **welcome**, sent once after the connection opens: `"message"` is
//!   the string `"Welcome"` (that is how every public client recognises it;
//!   its other fields are not documented);
//! - a **data message**: `"message"` is the server's message counter, `"time"`
//!   its Unix time (s), and each sensor is an object under its number as a
//!   string key (`"1"`, `"2"`, ...) holding `"sensor"`, `"model"`,
//!   `"taxels"`, the raw counts `"data"` (x, y, z per taxel, taxel by taxel:
//!   a comma-separated hex string, or a list of integers) and, when the
//!   server's force calibration is on, `"calibrated"` (x, y, z in newtons).
//!
//! [`parse_message`] turns one message into a [`XelaEvent`] or a
//! [`XelaParseError`] naming the field at fault; [`XelaDecoder`] adds the
//! counters, the message counter's gaps and the check of the configured
//! sensors ([`Expected`]). [`encode_scan`] writes scans in each of the
//! server's encodings, for fixtures and the emulator.

mod decoder;
mod encode;
mod error;
mod message;
mod parse;

pub use decoder::{
    Decoded, Expected, ExpectedSensor, MessageGap, XelaCounters, XelaDecoder, XelaError, XelaMismatch,
};
pub use encode::{WireStyle, encode_scan, encode_welcome};
pub use error::XelaParseError;
pub use message::{TaxelCounts, TaxelForce, WELCOME, XelaEvent, XelaScan, XelaSensorScan, XelaWelcome};
pub use parse::parse_message;

/// The port `xela_server` listens on unless started with `--port`.
pub const DEFAULT_PORT: u16 = 5000;

#[cfg(test)]
mod tests;
