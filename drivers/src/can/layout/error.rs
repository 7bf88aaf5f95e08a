//! Why a CAN layout cannot describe the configured sensors.

use thiserror::Error;

/// A layout that cannot describe the configured sensors.
#[derive(Clone, Debug, Error, PartialEq, Eq)]
pub enum CanMapError {
    /// An entry that is none or several of the three forms, or names an
    /// unknown sensor, or reaches beyond its sensor.
    #[error("hw.tactile.map[{index}]: {why}")]
    Entry {
        /// Index of the entry in the file.
        index: usize,
        /// What is wrong.
        why: String,
    },
    /// Two taxels on one id.
    #[error("CAN id 0x{id:X} is given twice: by {first} and by {second}")]
    SharedId {
        /// The id.
        id: u32,
        /// The first setting.
        first: String,
        /// The second setting.
        second: String,
    },
    /// A taxel of a configured sensor that no id carries.
    #[error("hw.tactile.map maps no CAN id to taxel {taxel} of sensor `{sensor}` (every taxel needs one)")]
    Unmapped {
        /// The sensor.
        sensor: String,
        /// The taxel.
        taxel: u32,
    },
    /// A taxel mapped twice.
    #[error("taxel {taxel} of sensor `{sensor}` is mapped twice (ids 0x{first:X} and 0x{second:X})")]
    TaxelTwice {
        /// The sensor.
        sensor: String,
        /// The taxel.
        taxel: u32,
        /// The first id.
        first: u32,
        /// The second id.
        second: u32,
    },
    /// An id beyond 11 (or 29) bits.
    #[error("{key} = 0x{id:X} is beyond the {bits}-bit CAN id range")]
    IdRange {
        /// The setting.
        key: String,
        /// The id.
        id: u32,
        /// 11 or 29.
        bits: u8,
    },
    /// A bad payload format.
    #[error("{0}")]
    Payload(String),
    /// A command frame that does not fit CAN.
    #[error(
        "{key}: id 0x{id:X} with {len} data bytes is not a CAN frame (at most 8 bytes; 11-bit id unless `extended = true`)"
    )]
    Command {
        /// The setting.
        key: String,
        /// The id.
        id: u32,
        /// Data bytes given.
        len: usize,
    },
}
