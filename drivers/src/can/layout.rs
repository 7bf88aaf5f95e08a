//! CAN tactile layouts as data: which CAN id carries which taxel of which
//! sensor, how a frame's payload holds x, y and z, which command frames
//! start and stop the stream, and how frames become scans. Everything here
//! is configuration and pure functions; [`decoder`] turns frames into
//! scans without I/O.
//!
//! Two id schemes:
//! - the legacy layout (`taxel_base_id`, `taxels_per_module`: taxel `t` of
//!   the sensor on module `m` at `taxel_base_id + m * taxels_per_module + t`),
//!   the 2018-19 third-party layout of ARQ-CRISP/uskin_can_drivers and
//!   o2as `o2as_xela_sensor`, not verified against XELA;
//! - an explicit map (`[[hw.tactile.map]]`): single ids, id ranges, and
//!   row/column patterns, see [`MapEntry`].
//!
//! See `docs/protocols.md`, section "CAN", for what is verified and what is not.

use std::collections::HashMap;

use serde::{Deserialize, Serialize};

use crate::can::protocol::{CanFrame, MAX_STANDARD_ID};
use crate::sensors::HwSensor;

pub mod decoder;
mod error;
mod payload;
mod resolved;

pub use decoder::{CanLayoutDecoder, LayoutScan};
pub use error::CanMapError;
pub use payload::{ByteOrder, Payload, PayloadFormat, ValidityByte};
pub use resolved::{IdKey, ResolvedLayout, ScanMode};

/// Largest extended (29-bit) CAN identifier.
pub const MAX_EXTENDED_ID: u32 = 0x1FFF_FFFF;

/// A command frame the host sends (`{ id = 0x201, data = [7, 0] }`).
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CommandFrame {
    /// The identifier.
    pub id: u32,
    /// A 29-bit identifier.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub extended: bool,
    /// 0 to 8 data bytes.
    #[serde(default)]
    pub data: Vec<u8>,
}

impl CommandFrame {
    /// The frame, or an error naming `key` when it does not fit CAN.
    pub fn frame(&self, key: &str) -> Result<CanFrame, CanMapError> {
        CanFrame::new(self.id, self.extended, &self.data).ok_or_else(|| CanMapError::Command {
            key: key.to_string(),
            id: self.id,
            len: self.data.len(),
        })
    }
}

/// One entry of an explicit id map (`[[hw.tactile.map]]`). Exactly one of
/// three forms, each for the sensor named `sensor`:
///
/// - one id: `{ sensor = "thumb", id = 0x201, taxel = 0 }`;
/// - a range: `{ sensor = "thumb", first_id = 0x300, count = 16,
///   first_taxel = 0, id_step = 1 }`: ids `first_id + k * id_step` carry
///   taxels `first_taxel + k`, `k < count` (`count` defaults to the rest of
///   the sensor's taxels, `first_taxel` to 0, `id_step` to 1);
/// - a row/column pattern: `{ sensor = "thumb", base_id = 0x400,
///   row_stride = 0x10, col_stride = 1 }`: taxel `(row, col)` (row-major
///   taxel `row * cols + col`) at `base_id + row * row_stride + col * col_stride`,
///   for every row and column of the sensor.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MapEntry {
    /// The sensor (`[[hw.tactile.sensors]]` name).
    pub sensor: String,
    /// 29-bit identifiers.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub extended: bool,
    /// One id (with `taxel`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub id: Option<u32>,
    /// The taxel of `id` (row-major index in the sensor).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub taxel: Option<u32>,
    /// First id of a range.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub first_id: Option<u32>,
    /// Taxels in a range.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub count: Option<u32>,
    /// Taxel of `first_id`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub first_taxel: Option<u32>,
    /// Id step between consecutive taxels of a range.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub id_step: Option<u32>,
    /// Id of taxel (0, 0) of a row/column pattern.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub base_id: Option<u32>,
    /// Id step from one row to the next.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub row_stride: Option<u32>,
    /// Id step from one column to the next.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub col_stride: Option<u32>,
}

/// One taxel's id: `(sensor index, taxel, id, the setting that gives it)`.
pub type Assignment = (usize, u32, IdKey, String);

/// Per slot its id and setting, and the slot of each id.
type SlotTable = (Vec<(IdKey, String)>, HashMap<IdKey, usize>);

fn check_id(key: &str, id: u32, extended: bool) -> Result<(), CanMapError> {
    let (max, bits) = if extended { (MAX_EXTENDED_ID, 29) } else { (MAX_STANDARD_ID, 11) };
    if id > max {
        return Err(CanMapError::IdRange { key: key.to_string(), id, bits });
    }
    Ok(())
}

/// Builds the slot table from `(sensor index, taxel, id, key)` assignments.
fn resolve_slots(sensors: &[HwSensor], assignments: Vec<Assignment>) -> Result<SlotTable, CanMapError> {
    let offsets: Vec<usize> = sensors
        .iter()
        .scan(0usize, |acc, s| {
            let o = *acc;
            *acc += s.taxels();
            Some(o)
        })
        .collect();
    let total = sensors.iter().map(HwSensor::taxels).sum();
    let mut slots: Vec<Option<(IdKey, String)>> = vec![None; total];
    let mut by_id: HashMap<IdKey, usize> = HashMap::new();
    for (s, taxel, (id, ext), key) in assignments {
        check_id(&key, id, ext)?;
        let slot = offsets[s] + taxel as usize;
        if let Some(&other) = by_id.get(&(id, ext)) {
            let first = slots[other].as_ref().map(|(_, k)| k.clone()).unwrap_or_default();
            return Err(CanMapError::SharedId { id, first, second: key });
        }
        if let Some(((first, _), _)) = &slots[slot] {
            let sensor = sensors[s].name.clone();
            return Err(CanMapError::TaxelTwice { sensor, taxel, first: *first, second: id });
        }
        by_id.insert((id, ext), slot);
        slots[slot] = Some(((id, ext), key));
    }
    let mut out = Vec::with_capacity(total);
    for (s, sensor) in sensors.iter().enumerate() {
        for t in 0..sensor.taxels() {
            match slots[offsets[s] + t].take() {
                Some(x) => out.push(x),
                None => return Err(CanMapError::Unmapped { sensor: sensor.name.clone(), taxel: t as u32 }),
            }
        }
    }
    Ok((out, by_id))
}

/// The legacy ids: taxel `t` of the sensor on module `m` at
/// `taxel_base_id + m * taxels_per_module + t`.
pub fn legacy_assignments(
    sensors: &[HwSensor],
    taxel_base_id: u32,
    taxels_per_module: u16,
) -> Vec<Assignment> {
    let per = u64::from(taxels_per_module);
    let mut out = Vec::new();
    for (s, sensor) in sensors.iter().enumerate() {
        for t in 0..sensor.taxels() as u64 {
            let offset = u64::from(sensor.module) * per + t;
            let id = u32::try_from(u64::from(taxel_base_id) + offset).unwrap_or(u32::MAX);
            out.push((s, t as u32, (id, false), format!("hw.tactile.taxel_base_id + {offset}")));
        }
    }
    out
}

/// The assignments of an explicit map.
pub fn map_assignments(sensors: &[HwSensor], map: &[MapEntry]) -> Result<Vec<Assignment>, CanMapError> {
    let mut out = Vec::new();
    for (index, e) in map.iter().enumerate() {
        let bad = |why: String| CanMapError::Entry { index, why };
        let s = sensors
            .iter()
            .position(|x| x.name == e.sensor)
            .ok_or_else(|| bad(format!("sensor `{}` is not in hw.tactile.sensors", e.sensor)))?;
        let sensor = &sensors[s];
        let taxels = sensor.taxels() as u64;
        let key = |k: u64| format!("hw.tactile.map[{index}] (taxel {k})");
        let forms = [e.id.is_some(), e.first_id.is_some(), e.base_id.is_some()];
        if forms.iter().filter(|f| **f).count() != 1 {
            return Err(bad("give exactly one of `id` (with `taxel`), `first_id` (a range) and `base_id` \
                            (a row/column pattern)"
                .into()));
        }
        let stray = [
            ("taxel", e.taxel.is_some() && e.id.is_none()),
            ("count", e.count.is_some() && e.first_id.is_none()),
            ("first_taxel", e.first_taxel.is_some() && e.first_id.is_none()),
            ("id_step", e.id_step.is_some() && e.first_id.is_none()),
            ("row_stride", e.row_stride.is_some() && e.base_id.is_none()),
            ("col_stride", e.col_stride.is_some() && e.base_id.is_none()),
        ];
        if let Some((key, _)) = stray.iter().find(|(_, s)| *s) {
            return Err(bad(format!("`{key}` does not belong to this form of entry")));
        }
        let mut push = |taxel: u64, id: u64| -> Result<(), CanMapError> {
            if taxel >= taxels {
                return Err(bad(format!("taxel {taxel} is beyond sensor `{}`'s {taxels} taxels", e.sensor)));
            }
            let id = u32::try_from(id).unwrap_or(u32::MAX);
            out.push((s, taxel as u32, (id, e.extended), key(taxel)));
            Ok(())
        };
        if let Some(id) = e.id {
            let taxel = e.taxel.ok_or_else(|| bad("`id` needs `taxel`".into()))?;
            push(u64::from(taxel), u64::from(id))?;
        } else if let Some(first) = e.first_id {
            let first_taxel = u64::from(e.first_taxel.unwrap_or(0));
            let count = e.count.map_or(taxels.saturating_sub(first_taxel), u64::from);
            let step = u64::from(e.id_step.unwrap_or(1));
            for k in 0..count.min(taxels + 1) {
                push(first_taxel + k, u64::from(first) + k * step)?;
            }
        } else if let Some(base) = e.base_id {
            let (rs, cs) = (u64::from(e.row_stride.unwrap_or(0)), u64::from(e.col_stride.unwrap_or(1)));
            if e.row_stride.is_none() {
                return Err(bad(
                    "a `base_id` pattern needs `row_stride` (and `col_stride`, default 1)".into()
                ));
            }
            for row in 0..u64::from(sensor.rows) {
                for col in 0..u64::from(sensor.cols) {
                    push(row * u64::from(sensor.cols) + col, u64::from(base) + row * rs + col * cs)?;
                }
            }
        }
    }
    Ok(out)
}

/// Resolves a layout: the slots of `assignments`, the payload, the
/// command frames (`(frame setting, key)`) and the scan mode.
pub fn resolve(
    sensors: &[HwSensor],
    assignments: Vec<Assignment>,
    payload: PayloadFormat,
    start: &[(&CommandFrame, String)],
    stop: &[(&CommandFrame, String)],
    mode: ScanMode,
) -> Result<ResolvedLayout, CanMapError> {
    payload.validate()?;
    let (slots, by_id) = resolve_slots(sensors, assignments)?;
    let frames = |list: &[(&CommandFrame, String)]| -> Result<Vec<(CanFrame, String)>, CanMapError> {
        list.iter().map(|(c, k)| Ok((c.frame(k)?, k.clone()))).collect()
    };
    let (start, stop) = (frames(start)?, frames(stop)?);
    for (f, k) in start.iter().chain(&stop) {
        if let Some(&slot) = by_id.get(&(f.id, f.extended)) {
            let first = slots[slot].1.clone();
            return Err(CanMapError::SharedId { id: f.id, first, second: k.clone() });
        }
    }
    Ok(ResolvedLayout { slots, by_id, payload, start, stop, scan_start_id: None, mode })
}

#[cfg(test)]
mod tests;
