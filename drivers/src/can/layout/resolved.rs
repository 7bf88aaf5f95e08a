//! A layout resolved against the configured sensors, and how its frames
//! become scans: what [`super::decoder`] runs on.

use std::collections::HashMap;

use serde::{Deserialize, Serialize};

use super::payload::PayloadFormat;
use crate::can::protocol::CanFrame;

/// How taxel frames become scans.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ScanMode {
    /// A scan is emitted when every mapped taxel has arrived; a scan that
    /// is still incomplete when the next one begins (the first mapped
    /// taxel's frame, a taxel seen twice, or the scan-start frame) is
    /// counted as incomplete and dropped.
    #[default]
    #[serde(alias = "start_frame")]
    Complete,
    /// The latest value of every taxel, emitted at `rate_hz` once every
    /// taxel has been seen (for boards that stream taxels independently).
    Latest,
}

/// A CAN id: `(id, extended)`.
pub type IdKey = (u32, bool);

/// A layout resolved against the configured sensors: one slot per taxel
/// of every sensor, in scan order (sensor by sensor, row-major), and the
/// id of each.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ResolvedLayout {
    /// Per slot: its id and the setting it came from (for messages).
    pub slots: Vec<(IdKey, String)>,
    /// Slot of each id.
    pub by_id: HashMap<IdKey, usize>,
    /// How payloads hold the values.
    pub payload: PayloadFormat,
    /// Frames sent after opening the bus.
    pub start: Vec<(CanFrame, String)>,
    /// Frames sent when the source is dropped.
    pub stop: Vec<(CanFrame, String)>,
    /// An id that marks the start of a scan (legacy: none; frames of the
    /// first slot do).
    pub scan_start_id: Option<IdKey>,
    /// How frames become scans.
    pub mode: ScanMode,
}

impl ResolvedLayout {
    /// The frames of a scan of valid `values` (one per slot, in slot
    /// order), for emulators and tests.
    pub fn encode_scan(&self, values: &[slidetrack_core::RawTaxel]) -> Vec<CanFrame> {
        self.slots
            .iter()
            .zip(values)
            .filter_map(|(((id, ext), _), v)| CanFrame::new(*id, *ext, &self.payload.encode(*v)))
            .collect()
    }

    /// Every id the tactile source uses, with the setting that gives it.
    pub fn used_ids(&self) -> impl Iterator<Item = (IdKey, &str)> {
        let frames = self.start.iter().chain(&self.stop).map(|(f, k)| ((f.id, f.extended), k.as_str()));
        self.slots.iter().map(|(id, k)| (*id, k.as_str())).chain(frames)
    }
}
