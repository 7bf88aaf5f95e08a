//! Tactile sensing: three fingertips, each with one 3-axis (x, y, z) module.

use std::ops::{Index, IndexMut};

use serde::{Deserialize, Serialize};

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

/// One value per finger, serialized as `{"thumb": .., "index": .., "middle": ..}`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct PerFinger<T> {
    /// The thumb's value.
    pub thumb: T,
    /// The index finger's value.
    pub index: T,
    /// The middle finger's value.
    pub middle: T,
}

impl<T> PerFinger<T> {
    /// Builds each finger's value with `f`, in [`Finger::ALL`] order.
    pub fn from_fn(mut f: impl FnMut(Finger) -> T) -> PerFinger<T> {
        PerFinger { thumb: f(Finger::Thumb), index: f(Finger::Index), middle: f(Finger::Middle) }
    }

    /// From an array indexed by [`Finger::index`].
    pub fn from_array([thumb, index, middle]: [T; 3]) -> PerFinger<T> {
        PerFinger { thumb, index, middle }
    }

    /// As an array indexed by [`Finger::index`].
    pub fn into_array(self) -> [T; 3] {
        [self.thumb, self.index, self.middle]
    }

    /// Applies `f` to each finger's value.
    pub fn map<U>(self, mut f: impl FnMut(T) -> U) -> PerFinger<U> {
        PerFinger { thumb: f(self.thumb), index: f(self.index), middle: f(self.middle) }
    }
}

impl<T> Index<Finger> for PerFinger<T> {
    type Output = T;
    fn index(&self, finger: Finger) -> &T {
        match finger {
            Finger::Thumb => &self.thumb,
            Finger::Index => &self.index,
            Finger::Middle => &self.middle,
        }
    }
}

impl<T> IndexMut<Finger> for PerFinger<T> {
    fn index_mut(&mut self, finger: Finger) -> &mut T {
        match finger {
            Finger::Thumb => &mut self.thumb,
            Finger::Index => &mut self.index,
            Finger::Middle => &mut self.middle,
        }
    }
}

/// Which taxel of which sensor module each finger's values come from.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct TaxelRef {
    /// The module's index on the sensor bus.
    pub module: u32,
    /// The taxel's index within the module.
    pub taxel: u32,
}

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
