//! The bits of an ArUco marker, as a dictionary defines them.
//!
//! Rendering code (the simulated camera) and detection code (OpenCV's
//! dictionaries, in the calibration crate) meet here without depending on
//! each other.

use serde::{Deserialize, Serialize};
use thiserror::Error;

/// A marker pattern whose bit count does not match its size.
#[derive(Clone, Debug, Error, PartialEq, Eq)]
#[error("marker pattern {dictionary} id {id}: {bits_len} bits given for {cells}x{cells} cells")]
pub struct BadMarkerPattern {
    /// Dictionary name, for messages.
    pub dictionary: String,
    /// Marker id.
    pub id: u32,
    /// Inner cells per side.
    pub cells: usize,
    /// Number of bits supplied.
    pub bits_len: usize,
}

/// The bits of one ArUco marker, as the caller's dictionary defines them.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct MarkerPattern {
    /// Dictionary name (for example `DICT_6X6_250`), for messages and metadata.
    pub dictionary: String,
    /// Marker id within the dictionary.
    pub id: u32,
    /// Inner cells per side (6 for a 6x6 dictionary), without the black border.
    pub cells: usize,
    /// `cells * cells` bits, row-major from the marker's top-left as printed,
    /// 1 = white, 0 = black.
    pub bits: Vec<u8>,
}

impl MarkerPattern {
    /// Whether inner cell (`row`, `col`) is white; out-of-range cells are black (border).
    pub fn is_white(&self, row: usize, col: usize) -> bool {
        row < self.cells && col < self.cells && self.bits.get(row * self.cells + col).is_some_and(|&b| b != 0)
    }

    /// Checks that the bit count matches the size.
    pub fn validate(&self) -> Result<(), BadMarkerPattern> {
        if self.cells == 0 || self.bits.len() != self.cells * self.cells {
            return Err(BadMarkerPattern {
                dictionary: self.dictionary.clone(),
                id: self.id,
                cells: self.cells,
                bits_len: self.bits.len(),
            });
        }
        Ok(())
    }
}
