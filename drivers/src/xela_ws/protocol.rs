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

use thiserror::Error;

mod decoder;
mod encode;
mod parse;

pub use decoder::{
    Decoded, Expected, ExpectedSensor, MessageGap, XelaCounters, XelaDecoder, XelaError, XelaMismatch,
};
pub use encode::{WireStyle, encode_scan, encode_welcome};
pub use parse::parse_message;

/// The port `xela_server` listens on unless started with `--port`.
pub const DEFAULT_PORT: u16 = 5000;

/// The value of `"message"` in the welcome message.
pub const WELCOME: &str = "Welcome";

/// Raw counts of one taxel: `[x, y, z]` (16-bit magnetometer counts, not
/// calibrated).
pub type TaxelCounts = [u16; 3];

/// Calibrated force on one taxel: `[x, y, z]` in newtons.
pub type TaxelForce = [f64; 3];

/// What one WebSocket text message from `xela_server` carries.
#[derive(Clone, Debug, PartialEq)]
pub enum XelaEvent {
    /// The welcome sent when a client connects; it carries no scan.
    Welcome(XelaWelcome),
    /// One scan of every sensor the server reads.
    Data(XelaScan),
}

/// The welcome message.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct XelaWelcome {
    /// Its `"version"`, when it has one (server version and build, for
    /// example `1.7.7_161703`; not documented for the welcome).
    pub version: Option<String>,
}

/// One data message: a scan of every sensor.
#[derive(Clone, Debug, PartialEq)]
pub struct XelaScan {
    /// The server's message counter (`"message"`).
    pub message: u64,
    /// The server's clock when it sent the message (`"time"`, Unix time in
    /// seconds), when present. Kept as the server wrote it; the client's
    /// arrival instant is the time to use on the session clock.
    pub server_time_s: Option<f64>,
    /// The sensors, by increasing sensor number.
    pub sensors: Vec<XelaSensorScan>,
}

impl XelaScan {
    /// The scan of sensor `number`, if the message has it.
    pub fn sensor(&self, number: u32) -> Option<&XelaSensorScan> {
        self.sensors.iter().find(|s| s.sensor == number)
    }
}

/// One sensor's part of a data message.
#[derive(Clone, Debug, PartialEq)]
pub struct XelaSensorScan {
    /// The sensor's number: its key in the message (`"1"` is sensor 1), the
    /// position the server's configuration gives it.
    pub sensor: u32,
    /// The model the server reports (`"model"`, for example `uSPa44`; the
    /// server may write it in capitals, as `USPA35`).
    pub model: String,
    /// The sensor's own time stamp (`"time"`, Unix time in seconds), when present.
    pub time_s: Option<f64>,
    /// Raw counts, one `[x, y, z]` per taxel, in the server's taxel order.
    pub taxels: Vec<TaxelCounts>,
    /// Calibrated forces (N), one `[x, y, z]` per taxel, when the server's
    /// force calibration is on (`"calibrated"` absent, `null` or empty: `None`).
    pub calibrated: Option<Vec<TaxelForce>>,
}

/// Why a message is not a welcome nor a well-formed data message. Each
/// variant names the field at fault (`2.data` is field `data` of sensor 2).
#[derive(Clone, Debug, Error, PartialEq, Eq)]
pub enum XelaParseError {
    /// The text is not JSON.
    #[error("not JSON: {reason}")]
    Json {
        /// serde_json's description.
        reason: String,
        /// Line of the error (1-based).
        line: usize,
        /// Column of the error (1-based).
        column: usize,
    },
    /// A binary WebSocket message (the server sends text).
    #[error("a binary message of {bytes} bytes, not a JSON text message")]
    Binary {
        /// Its length.
        bytes: usize,
    },
    /// The JSON is not an object.
    #[error("the message is {found}, not a JSON object")]
    NotAnObject {
        /// The JSON type found.
        found: &'static str,
    },
    /// A required field is absent.
    #[error("`{field}` is missing")]
    Missing {
        /// The field.
        field: String,
    },
    /// A field has the wrong JSON type or an impossible value.
    #[error("`{field}` is {found}, expected {expected}")]
    WrongType {
        /// The field.
        field: String,
        /// What it should be.
        expected: &'static str,
        /// What it is.
        found: &'static str,
    },
    /// `"message"` is a string other than `"Welcome"`.
    #[error("`message` is the string {text:?}, neither a counter nor \"Welcome\"")]
    UnknownMessage {
        /// The string (its first 64 characters).
        text: String,
    },
    /// A data message without any sensor object.
    #[error("message {message} has no sensor (no key made of digits)")]
    NoSensors {
        /// The message counter.
        message: u64,
    },
    /// A key made of digits that is not a sensor number.
    #[error("key `{key}` is not a sensor number (1 to 4294967295 without leading zeros)")]
    SensorKey {
        /// The key (its first 64 characters).
        key: String,
    },
    /// A sensor object whose `"sensor"` differs from its key.
    #[error("`{key}.sensor` is {found}, not {key}")]
    SensorNumber {
        /// The key.
        key: u32,
        /// The `"sensor"` value, as JSON (its first 64 characters).
        found: String,
    },
    /// `"sensors"` disagrees with the number of sensor objects.
    #[error("`sensors` is {declared} but the message has {found} sensor objects")]
    SensorCount {
        /// The `"sensors"` value.
        declared: u64,
        /// Sensor objects in the message.
        found: usize,
    },
    /// A token of a hex `data` string that is not a 16-bit hex number.
    #[error("`{field}` value {index} is {token:?}, not a hexadecimal count 0 to FFFF")]
    Hex {
        /// The field.
        field: String,
        /// The value's index (0-based).
        index: usize,
        /// The token (its first 16 characters).
        token: String,
    },
    /// An element of an integer `data` list that is not a count 0 to 65535.
    #[error("`{field}` value {index} is {value}, not a count 0 to 65535")]
    Count {
        /// The field.
        field: String,
        /// The value's index (0-based).
        index: usize,
        /// The element, as JSON (its first 32 characters).
        value: String,
    },
    /// An element of `calibrated` that is not a number.
    #[error("`{field}` value {index} is {found}, not a number")]
    NotANumber {
        /// The field.
        field: String,
        /// The value's index (0-based).
        index: usize,
        /// The JSON type found.
        found: &'static str,
    },
    /// `data` or `calibrated` does not hold 3 values per taxel of `"taxels"`.
    #[error("`{field}` has {values} values, not 3 × {taxels} taxels")]
    Length {
        /// The field.
        field: String,
        /// Values found.
        values: usize,
        /// The sensor's `"taxels"`.
        taxels: u64,
    },
    /// `data` of a sensor without `"taxels"` is empty or not made of triples.
    #[error("`{field}` has {values} values, not a whole number (at least 1) of x, y, z triples")]
    NotTriples {
        /// The field.
        field: String,
        /// Values found.
        values: usize,
    },
}

#[cfg(test)]
mod tests;
