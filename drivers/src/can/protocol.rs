//! CAN frames as the decoders see them, and the legacy uSkin board layout
//! of the 2018-19 third-party drivers (ARQ-CRISP/uskin_can_drivers, o2as
//! `o2as_xela_sensor`; not verified against XELA, see `docs/protocols.md`):
//!
//! - the host starts streaming with a frame to `start_base_id | board`
//!   carrying `[7, 0]`;
//! - the board then sends, every scan, one frame per taxel at
//!   `taxel_base_id + taxel`: bytes 1-6 hold x, y, z as big-endian u16 raw
//!   counts; those drivers read byte 0 as a status byte (250 or more:
//!   invalid), which no public source explains.
//!
//! Frames become scans in [`crate::can::layout`], for this layout and others.

use serde::{Deserialize, Serialize};
use slidetrack_core::RawTaxel;
use thiserror::Error;

/// Largest standard (11-bit) CAN identifier.
pub const MAX_STANDARD_ID: u32 = 0x7FF;
/// A status byte at or above this marks the sample invalid, in the legacy drivers.
pub const INVALID_STATUS: u8 = 250;
/// Data of the start command.
pub const START_COMMAND: [u8; 2] = [7, 0];
/// Most taxels one board may have (ids must stay standard).
pub const MAX_CAN_TAXELS: u16 = 256;

/// A classic CAN 2.0 frame as the decoders see it (no I/O types).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct CanFrame {
    /// The identifier (11 bits, or 29 when `extended`).
    pub id: u32,
    /// A 29-bit identifier.
    pub extended: bool,
    len: u8,
    data: [u8; 8],
}

impl CanFrame {
    /// A data frame; `None` when `data` is longer than 8 bytes or `id` does not fit.
    pub fn new(id: u32, extended: bool, data: &[u8]) -> Option<CanFrame> {
        let max_id = if extended { 0x1FFF_FFFF } else { MAX_STANDARD_ID };
        if data.len() > 8 || id > max_id {
            return None;
        }
        let mut bytes = [0; 8];
        bytes[..data.len()].copy_from_slice(data);
        Some(CanFrame { id, extended, len: data.len() as u8, data: bytes })
    }

    /// A standard-id data frame; `None` when `id` or `data` does not fit.
    pub fn standard(id: u32, data: &[u8]) -> Option<CanFrame> {
        CanFrame::new(id, false, data)
    }

    /// A standard frame from `id` masked to 11 bits and the first 8 bytes
    /// of `data`, for ids validated beforehand.
    pub(crate) fn standard_masked(id: u32, data: &[u8]) -> CanFrame {
        let len = data.len().min(8);
        let mut bytes = [0; 8];
        bytes[..len].copy_from_slice(&data[..len]);
        CanFrame { id: id & MAX_STANDARD_ID, extended: false, len: len as u8, data: bytes }
    }

    /// The data bytes.
    pub fn data(&self) -> &[u8] {
        &self.data[..usize::from(self.len)]
    }
}

/// A CAN layout whose ids do not fit.
#[derive(Clone, Debug, Error, PartialEq, Eq)]
pub enum CanLayoutError {
    /// An identifier beyond the 11-bit range.
    #[error("{what} 0x{id:X} is beyond the standard CAN range (0x7FF)")]
    IdOutOfRange {
        /// Which id.
        what: &'static str,
        /// Its value.
        id: u32,
    },
    /// A taxel count of zero or more than [`MAX_CAN_TAXELS`].
    #[error("a board has 1 to {MAX_CAN_TAXELS} taxels, not {taxels}")]
    TaxelCount {
        /// The count given.
        taxels: u16,
    },
}

/// Where one uSkin board sits on the bus.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct XelaCanLayout {
    /// The board id (combined into the start command's id).
    pub board: u8,
    /// Base of the start command's id (`start_base_id | board`).
    pub start_base_id: u32,
    /// Id of taxel 0's frames; taxel `t` uses `taxel_base_id + t`.
    pub taxel_base_id: u32,
    /// Taxels on the board, numbered from 0.
    pub taxels: u16,
}

impl Default for XelaCanLayout {
    fn default() -> Self {
        XelaCanLayout { board: 1, start_base_id: 0x200, taxel_base_id: 0x710, taxels: 16 }
    }
}

impl XelaCanLayout {
    /// Checks that every id fits in 11 bits.
    pub fn validate(&self) -> Result<(), CanLayoutError> {
        if self.taxels == 0 || self.taxels > MAX_CAN_TAXELS {
            return Err(CanLayoutError::TaxelCount { taxels: self.taxels });
        }
        let start = self.start_base_id | u32::from(self.board);
        if start > MAX_STANDARD_ID {
            return Err(CanLayoutError::IdOutOfRange { what: "start command id", id: start });
        }
        let last = self.taxel_base_id + u32::from(self.taxels) - 1;
        if last > MAX_STANDARD_ID {
            return Err(CanLayoutError::IdOutOfRange { what: "last taxel id", id: last });
        }
        Ok(())
    }

    /// The frame that starts the board's stream.
    pub fn start_command(&self) -> CanFrame {
        CanFrame::standard_masked(self.start_base_id | u32::from(self.board), &START_COMMAND)
    }

    /// The taxel a frame carries, if it is one of this board's taxel frames.
    pub fn taxel_of(&self, frame: &CanFrame) -> Option<u16> {
        if frame.extended {
            return None;
        }
        let t = frame.id.checked_sub(self.taxel_base_id)?;
        (t < u32::from(self.taxels)).then_some(t as u16)
    }

    /// The frame a board sends for `taxel` (for emulators and tests):
    /// status 0 when valid, [`INVALID_STATUS`] otherwise.
    pub fn taxel_frame(&self, taxel: u16, value: RawTaxel, valid: bool) -> CanFrame {
        let mut data = [0; 8];
        data[0] = if valid { 0 } else { INVALID_STATUS };
        for (k, v) in value.iter().enumerate() {
            data[1 + 2 * k..3 + 2 * k].copy_from_slice(&v.to_be_bytes());
        }
        CanFrame::standard_masked(self.taxel_base_id + u32::from(taxel), &data)
    }
}

#[cfg(test)]
mod tests;
