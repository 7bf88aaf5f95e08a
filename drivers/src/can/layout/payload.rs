//! How one taxel frame's payload holds a taxel's x, y and z, and what it
//! decodes to.

use serde::{Deserialize, Serialize};

use super::error::CanMapError;

/// Byte order of the 16-bit values in a taxel frame.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ByteOrder {
    /// Most significant byte first (the legacy layout's drivers read this).
    #[default]
    Big,
    /// Least significant byte first.
    Little,
}

/// A validity check on one payload byte: the sample is invalid when the
/// byte is `below` or more. Off unless configured: no public source
/// documents such a byte for XELA boards.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ValidityByte {
    /// Offset of the byte in the payload (0-7).
    pub byte: u8,
    /// Values at or above this mark the sample invalid.
    pub below: u8,
}

/// How one taxel frame's payload holds the taxel's x, y and z (unsigned
/// 16-bit raw counts).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PayloadFormat {
    /// Byte order of x, y and z.
    pub byte_order: ByteOrder,
    /// Offset of x's first byte in the payload (0-6).
    pub x: u8,
    /// Offset of y's first byte.
    pub y: u8,
    /// Offset of z's first byte.
    pub z: u8,
    /// A status byte that marks invalid samples; none by default.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub valid: Option<ValidityByte>,
}

impl Default for PayloadFormat {
    /// The legacy layout's drivers: x, y, z big-endian at bytes 1, 3, 5.
    fn default() -> Self {
        PayloadFormat { byte_order: ByteOrder::Big, x: 1, y: 3, z: 5, valid: None }
    }
}

/// What a payload decoded to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Payload {
    /// `[x, y, z]` raw counts.
    Valid(slidetrack_core::RawTaxel),
    /// The validity byte marked it invalid.
    Invalid,
    /// Shorter than the format needs.
    TooShort,
}

impl PayloadFormat {
    /// Bytes a payload needs.
    pub fn len(&self) -> usize {
        let values = [self.x, self.y, self.z].iter().map(|&o| usize::from(o) + 2).max().unwrap_or(0);
        values.max(self.valid.map_or(0, |v| usize::from(v.byte) + 1))
    }

    /// Always false: a format holds three values.
    pub fn is_empty(&self) -> bool {
        false
    }

    /// Checks that the values fit 8 bytes and overlap neither each other
    /// nor the validity byte.
    pub fn validate(&self) -> Result<(), CanMapError> {
        let mut used = [None::<&'static str>; 8];
        let fields = [("x", self.x, 2), ("y", self.y, 2), ("z", self.z, 2)];
        let valid = self.valid.map(|v| ("valid.byte", v.byte, 1));
        for (name, offset, width) in fields.into_iter().chain(valid) {
            for k in usize::from(offset)..usize::from(offset) + width {
                let Some(slot) = used.get_mut(k) else {
                    return Err(CanMapError::Payload(format!(
                        "hw.tactile.payload.{name} = {offset} ends beyond the 8 bytes of a CAN frame"
                    )));
                };
                if let Some(other) = slot {
                    return Err(CanMapError::Payload(format!(
                        "hw.tactile.payload.{name} and .{other} share byte {k}"
                    )));
                }
                *slot = Some(name);
            }
        }
        Ok(())
    }

    /// Decodes one taxel frame's payload.
    pub fn decode(&self, data: &[u8]) -> Payload {
        if data.len() < self.len() {
            return Payload::TooShort;
        }
        if let Some(v) = self.valid
            && data[usize::from(v.byte)] >= v.below
        {
            return Payload::Invalid;
        }
        let read = |o: u8| {
            let b = [data[usize::from(o)], data[usize::from(o) + 1]];
            match self.byte_order {
                ByteOrder::Big => u16::from_be_bytes(b),
                ByteOrder::Little => u16::from_le_bytes(b),
            }
        };
        Payload::Valid([read(self.x), read(self.y), read(self.z)])
    }

    /// The payload of a valid sample (for emulators and tests): the values
    /// at their offsets, every other byte 0 (a validity byte, too).
    pub fn encode(&self, value: slidetrack_core::RawTaxel) -> Vec<u8> {
        let mut data = vec![0; self.len()];
        for (offset, v) in [self.x, self.y, self.z].into_iter().zip(value) {
            let bytes = match self.byte_order {
                ByteOrder::Big => v.to_be_bytes(),
                ByteOrder::Little => v.to_le_bytes(),
            };
            let o = usize::from(offset);
            data[o..o + 2].copy_from_slice(&bytes);
        }
        data
    }
}
