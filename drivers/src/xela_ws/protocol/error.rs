//! Why a message of `xela_server` does not parse.

use thiserror::Error;

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
