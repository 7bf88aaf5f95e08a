//! Tactile sensing: three fingertips, each with one 3-axis (x, y, z) module.

use serde::{Deserialize, Serialize};

use crate::session::{PerFinger, TaxelRef};
use crate::{DecoderCounters, DeviceError, TimeNs};

/// A finger of the hand that carries a tactile module.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Finger {
    /// The thumb, alone on one side of the object.
    Thumb,
    /// The index finger, beside the middle finger opposite the thumb.
    Index,
    /// The middle finger.
    Middle,
}

impl Finger {
    /// All fingers, in the order used by every per-finger array of the project.
    pub const ALL: [Finger; 3] = [Finger::Thumb, Finger::Index, Finger::Middle];

    /// Index into per-finger arrays.
    pub fn index(self) -> usize {
        self as usize
    }

    /// Lower-case name (`thumb`, `index`, `middle`), as used in channel fields.
    pub fn name(self) -> &'static str {
        match self {
            Finger::Thumb => "thumb",
            Finger::Index => "index",
            Finger::Middle => "middle",
        }
    }
}

/// The three raw channels of a module, in the module's own frame.
pub const AXES: [&str; 3] = ["x", "y", "z"];

/// Raw counts of one tactile module: `[x, y, z]`.
pub type RawTaxel = [u16; 3];

/// One scan of the three fingertip modules.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct TactileSample {
    /// Acquisition time on the session clock.
    pub t: TimeNs,
    /// The device's own frame counter (wraps as the device wraps it).
    pub sequence: u64,
    /// Raw counts per finger, indexed by [`Finger::index`], each `[x, y, z]`.
    pub raw: [RawTaxel; 3],
}

/// Static facts about a tactile source.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TactileInfo {
    /// Name of the device, for messages (`sim`, `/dev/ttyACM0`, `can0`).
    pub device: String,
    /// Nominal sample rate (Hz).
    pub rate_hz: f64,
    /// The sensor module and taxel each finger's values come from, when the
    /// device has several (`None`: one module per finger, taxel 0).
    #[serde(default)]
    pub taxels: Option<PerFinger<TaxelRef>>,
}

/// A source of tactile samples.
///
/// # Contract
/// - `read` blocks until the next scan is complete and returns it; on
///   simulated time it advances the simulation to that scan instead.
/// - It returns [`crate::ErrorKind::Timeout`] when no scan arrives within
///   the backend's timeout (50 ms unless configured), and
///   [`crate::ErrorKind::Disconnected`] when the device is gone; after a
///   `Disconnected` error every later call fails too.
/// - Sample times are non-decreasing; sequence numbers increase by one per
///   scan unless the device dropped scans.
pub trait TactileSource: Send {
    /// The next scan.
    fn read(&mut self) -> Result<TactileSample, DeviceError>;
    /// What this source is.
    fn info(&self) -> TactileInfo;
    /// Counters of the source's decoder (frames, CRC errors, resyncs, gaps,
    /// incomplete scans), for backends that decode a byte or frame stream;
    /// `None` for the others.
    fn counters(&self) -> Option<DecoderCounters> {
        None
    }
}
