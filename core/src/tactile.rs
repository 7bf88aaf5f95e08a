//! Tactile sensing: sensors (patches or fingertip modules) of 3-axis (x, y,
//! z) taxels, carried by the fingers, and what each finger's reading is.

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

/// Raw counts of one taxel: `[x, y, z]`.
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

/// One tactile sensor of a rig: a patch or fingertip module of
/// `rows x cols` taxels, each measuring x, y and z (raw counts).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SensorLayout {
    /// Unique name, used in channel fields and dEKF channel names (`thumb`, `left`).
    pub name: String,
    /// Sensor model (`uSPa44`, `uSPa46`, `sim`), as the vendor names it.
    pub model: String,
    /// The finger (or gripper pad) that carries the sensor.
    pub finger: String,
    /// Rows of the taxel grid.
    pub rows: u32,
    /// Columns of the taxel grid; taxels are numbered row by row.
    pub cols: u32,
    /// Taxel centres in the sensor's own frame (mm), in taxel order, when known.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub taxel_positions_mm: Option<Vec<[f64; 2]>>,
}

impl SensorLayout {
    /// A sensor of `rows x cols` taxels with unknown taxel positions.
    pub fn grid(name: &str, model: &str, finger: &str, rows: u32, cols: u32) -> SensorLayout {
        SensorLayout {
            name: name.into(),
            model: model.into(),
            finger: finger.into(),
            rows,
            cols,
            taxel_positions_mm: None,
        }
    }

    /// Number of taxels.
    pub fn taxels(&self) -> usize {
        self.rows as usize * self.cols as usize
    }
}

/// A layout that cannot describe a scan.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum LayoutError {
    /// No sensor at all.
    #[error("the tactile layout has no sensor")]
    Empty,
    /// Two sensors share a name.
    #[error("two tactile sensors are named `{name}`")]
    DuplicateName {
        /// The name.
        name: String,
    },
    /// A sensor of zero taxels.
    #[error("tactile sensor `{name}` has {rows} x {cols} taxels; it needs at least one")]
    NoTaxels {
        /// The sensor.
        name: String,
        /// Its rows.
        rows: u32,
        /// Its columns.
        cols: u32,
    },
    /// Taxel positions that do not match the grid.
    #[error("tactile sensor `{name}` lists {positions} taxel positions for {taxels} taxels")]
    Positions {
        /// The sensor.
        name: String,
        /// Positions given.
        positions: usize,
        /// Taxels of the grid.
        taxels: usize,
    },
    /// A finger reading of a sensor the layout does not have.
    #[error(
        "finger `{finger}` reads tactile sensor `{sensor}`, which the layout does not have (sensors: {known})"
    )]
    UnknownSensor {
        /// The finger.
        finger: &'static str,
        /// The sensor it names.
        sensor: String,
        /// The sensors of the layout.
        known: String,
    },
    /// A finger reading of a taxel beyond its sensor.
    #[error("finger `{finger}` reads taxel {taxel} of tactile sensor `{sensor}`, which has {taxels} (0..={max})", max = taxels.saturating_sub(1))]
    TaxelOutOfRange {
        /// The finger.
        finger: &'static str,
        /// The sensor.
        sensor: String,
        /// The taxel asked for.
        taxel: u32,
        /// Taxels of the sensor.
        taxels: usize,
    },
    /// A sensor's values with the wrong number of taxels (or none).
    #[error("tactile sensor `{name}` has {expected} taxels in the layout but {got} in the data")]
    SensorSize {
        /// The sensor.
        name: String,
        /// Taxels in the layout.
        expected: usize,
        /// Taxels in the data.
        got: usize,
    },
    /// A scan whose taxel count does not match the layout.
    #[error("a tactile scan of {got} taxels does not match the layout's {expected}")]
    ScanSize {
        /// Taxels in the layout.
        expected: usize,
        /// Taxels in the scan.
        got: usize,
    },
}

/// Every tactile sensor of a rig, in scan order: a scan holds the taxels of
/// the first sensor, then those of the second, and so on.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TactileLayout {
    /// The sensors, in scan order.
    pub sensors: Vec<SensorLayout>,
}

impl TactileLayout {
    /// The thesis's hand (Sec. 6.2.1): one single-taxel module on each of
    /// thumb, index and middle finger, named after its finger.
    pub fn one_module_per_finger(model: &str) -> TactileLayout {
        TactileLayout {
            sensors: Finger::ALL
                .iter()
                .map(|f| SensorLayout::grid(f.name(), model, f.name(), 1, 1))
                .collect(),
        }
    }

    /// Taxels of all sensors together: the length of a scan.
    pub fn taxel_count(&self) -> usize {
        self.sensors.iter().map(SensorLayout::taxels).sum()
    }

    /// The sensor called `name`, with the range of its taxels in a scan.
    pub fn sensor(&self, name: &str) -> Option<(&SensorLayout, std::ops::Range<usize>)> {
        self.sensor_ranges().find(|(s, _)| s.name == name)
    }

    /// Each sensor with the range of its taxels in a scan.
    pub fn sensor_ranges(&self) -> impl Iterator<Item = (&SensorLayout, std::ops::Range<usize>)> {
        self.sensors.iter().scan(0, |start, s| {
            let range = *start..*start + s.taxels();
            *start = range.end;
            Some((s, range))
        })
    }

    /// The sensor names, comma-separated, for messages.
    pub fn sensor_names(&self) -> String {
        self.sensors.iter().map(|s| s.name.as_str()).collect::<Vec<_>>().join(", ")
    }

    /// Checks the layout describes scans: sensors with unique names, at
    /// least one taxel each, and as many positions as taxels when given.
    pub fn validate(&self) -> Result<(), LayoutError> {
        if self.sensors.is_empty() {
            return Err(LayoutError::Empty);
        }
        for (i, s) in self.sensors.iter().enumerate() {
            if self.sensors[..i].iter().any(|o| o.name == s.name) {
                return Err(LayoutError::DuplicateName { name: s.name.clone() });
            }
            if s.taxels() == 0 {
                return Err(LayoutError::NoTaxels { name: s.name.clone(), rows: s.rows, cols: s.cols });
            }
            if let Some(p) = &s.taxel_positions_mm
                && p.len() != s.taxels()
            {
                let (positions, taxels) = (p.len(), s.taxels());
                return Err(LayoutError::Positions { name: s.name.clone(), positions, taxels });
            }
        }
        Ok(())
    }
}

/// What a finger's reading is made of: the values the grasp controller
/// regulates (z) and the legacy `finger.axis` dEKF channels read.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FingerReading {
    /// The sensor on the finger.
    pub sensor: String,
    /// One taxel of it (as in the thesis, Sec. 6.2.1), or, when absent,
    /// the mean of all its taxels.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub taxel: Option<u32>,
}

impl FingerReading {
    /// Taxel `taxel` of `sensor`.
    pub fn taxel(sensor: &str, taxel: u32) -> FingerReading {
        FingerReading { sensor: sensor.into(), taxel: Some(taxel) }
    }

    /// The mean of every taxel of `sensor`.
    pub fn mean(sensor: &str) -> FingerReading {
        FingerReading { sensor: sensor.into(), taxel: None }
    }
}

/// The finger readings of a layout, resolved to taxel ranges of a scan.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FingerMap {
    /// Per finger, the taxels averaged into its reading (one for a single taxel).
    ranges: PerFinger<std::ops::Range<usize>>,
}

impl FingerMap {
    /// Resolves `readings` against `layout`.
    pub fn new(
        layout: &TactileLayout,
        readings: &PerFinger<FingerReading>,
    ) -> Result<FingerMap, LayoutError> {
        let mut ranges = PerFinger::from_fn(|_| 0..0);
        for f in Finger::ALL {
            let r = &readings[f];
            let (sensor, range) = layout.sensor(&r.sensor).ok_or_else(|| LayoutError::UnknownSensor {
                finger: f.name(),
                sensor: r.sensor.clone(),
                known: layout.sensor_names(),
            })?;
            ranges[f] = match r.taxel {
                None => range,
                Some(t) if (t as usize) < sensor.taxels() => {
                    range.start + t as usize..range.start + t as usize + 1
                }
                Some(taxel) => {
                    let (sensor, taxels) = (r.sensor.clone(), sensor.taxels());
                    return Err(LayoutError::TaxelOutOfRange { finger: f.name(), sensor, taxel, taxels });
                }
            };
        }
        Ok(FingerMap { ranges })
    }

    /// The taxels (range in a scan) averaged into `finger`'s reading.
    pub fn taxels(&self, finger: Finger) -> std::ops::Range<usize> {
        self.ranges[finger].clone()
    }

    /// Each finger's reading of `scan` (one `[x, y, z]` per taxel, in
    /// layout order): its taxel, or the mean of its taxels.
    pub fn read(&self, scan: &[[f64; 3]]) -> PerFinger<[f64; 3]> {
        PerFinger::from_fn(|f| {
            let taxels = &scan[self.ranges[f].clone()];
            let mut sum = [0.0; 3];
            for v in taxels {
                for a in 0..3 {
                    sum[a] += v[a];
                }
            }
            let n = taxels.len().max(1) as f64;
            sum.map(|s| s / n)
        })
    }
}

/// One scan of every taxel of every tactile sensor.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TactileSample {
    /// Acquisition time on the session clock.
    pub t: TimeNs,
    /// The device's own frame counter (wraps as the device wraps it).
    pub sequence: u64,
    /// Raw counts `[x, y, z]` of every taxel, in the order of the source's
    /// [`TactileLayout`] (sensor after sensor, taxels row by row).
    pub raw: Vec<RawTaxel>,
    /// The device's own time stamp of the scan (s, on the device's clock:
    /// `xela_server`'s Unix time), for devices that send one. Kept beside
    /// `t`, never used as the session time.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub device_time_s: Option<f64>,
    /// Calibrated forces `[x, y, z]` (N) of every taxel, in the order of
    /// `raw`, for devices that compute them (`xela_server` with its force
    /// calibration on).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub calibrated_n: Option<Vec<[f64; 3]>>,
    /// Reference forces `[x, y, z]` (N) on every taxel, in each taxel's
    /// frame and the order of `raw`, for sources that know them (the
    /// simulated rig with `[sim] reference_forces = true`): the target that
    /// `slidetrack calibrate tactile` fits counts to.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reference_n: Option<Vec<[f64; 3]>>,
}

impl TactileSample {
    /// A scan of raw counts only, as most devices send.
    pub fn new(t: TimeNs, sequence: u64, raw: Vec<RawTaxel>) -> TactileSample {
        TactileSample { t, sequence, raw, device_time_s: None, calibrated_n: None, reference_n: None }
    }
}

/// Static facts about a tactile source.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TactileInfo {
    /// Name of the device, for messages (`sim`, `/dev/ttyACM0`, `can0`).
    pub device: String,
    /// Nominal sample rate (Hz).
    pub rate_hz: f64,
    /// The sensors a scan holds.
    pub layout: TactileLayout,
    /// What each finger's reading is made of.
    pub fingers: PerFinger<FingerReading>,
}

impl TactileInfo {
    /// A source of the thesis's hand: one single-taxel module per finger.
    pub fn one_module_per_finger(device: &str, rate_hz: f64, model: &str) -> TactileInfo {
        TactileInfo {
            device: device.into(),
            rate_hz,
            layout: TactileLayout::one_module_per_finger(model),
            fingers: PerFinger::from_fn(|f| FingerReading::taxel(f.name(), 0)),
        }
    }

    /// The finger readings resolved against the layout (which is checked too).
    pub fn finger_map(&self) -> Result<FingerMap, LayoutError> {
        self.layout.validate()?;
        FingerMap::new(&self.layout, &self.fingers)
    }
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
