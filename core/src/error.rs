//! The one error type every device backend maps its failures onto.

use thiserror::Error;

/// What went wrong with a device, in terms generic code can react to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum ErrorKind {
    /// The device vanished (unplugged, port closed, interface down).
    Disconnected,
    /// No data within the allowed time.
    Timeout,
    /// Data arrived but could not be decoded (bad CRC, bad framing).
    Corrupt,
    /// Data was lost because a buffer overflowed.
    Overrun,
    /// The device reported a fault of its own (for example, in the simulator,
    /// an object that fell out of the hand).
    Fault,
    /// Anything else.
    Other,
}

impl std::fmt::Display for ErrorKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let s = match self {
            ErrorKind::Disconnected => "disconnected",
            ErrorKind::Timeout => "timeout",
            ErrorKind::Corrupt => "corrupt data",
            ErrorKind::Overrun => "overrun",
            ErrorKind::Fault => "device fault",
            ErrorKind::Other => "error",
        };
        f.write_str(s)
    }
}

/// A failure of a named device.
#[derive(Clone, Debug, Error, PartialEq, Eq)]
#[error("{device}: {kind}: {detail}")]
pub struct DeviceError {
    /// What kind of failure this is.
    pub kind: ErrorKind,
    /// The device, as the user named it (`/dev/ttyUSB0`, `can0`, `sim tactile`).
    pub device: String,
    /// Human-readable facts about the failure.
    pub detail: String,
}

impl DeviceError {
    /// A new error of `kind` on `device`.
    pub fn new(kind: ErrorKind, device: impl Into<String>, detail: impl Into<String>) -> Self {
        DeviceError { kind, device: device.into(), detail: detail.into() }
    }
}
