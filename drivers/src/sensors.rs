//! The tactile sensors of a real rig as configured (`[[hw.tactile.sensors]]`):
//! which module on the bus each sensor is, its layout, and the finger
//! readings (`hw.tactile.fingers`, optional: without it, each finger reads
//! taxel 0 of the sensor whose `finger` names it, see [`finger_readings`]).
//!
//! ```toml
//! [[hw.tactile.sensors]]
//! name = "thumb"      # unique; channel fields and dEKF channels use it
//! module = 0          # the module's index on the bus (serial module id, CAN module)
//! finger = "thumb"
//! model = "uSPa44"
//! rows = 4
//! cols = 4
//! [hw.tactile.fingers]
//! thumb = { sensor = "thumb", taxel = 5 }   # one taxel (the thesis)
//! index = { sensor = "index" }              # the mean of the patch
//! middle = { sensor = "middle", taxel = 5 }
//! ```

use serde::{Deserialize, Serialize};
use slidetrack_core::{
    Finger, FingerReading, LayoutError, PerFinger, SensorLayout, TactileInfo, TactileLayout,
};

/// One tactile sensor on the bus.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HwSensor {
    /// Unique name (`thumb`, `left`).
    pub name: String,
    /// The module's index on the bus: the serial frame's module id, or the
    /// CAN board's module (taxels `module * taxels_per_module ..`).
    pub module: u32,
    /// The finger (or gripper pad) carrying it.
    pub finger: String,
    /// Sensor model, as the vendor names it (recorded, not interpreted).
    pub model: String,
    /// Rows of taxels.
    pub rows: u32,
    /// Columns of taxels; `rows * cols` taxels are read from the module, row by row.
    pub cols: u32,
    /// Taxel centres in the sensor frame (mm), row by row, when known.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub taxel_positions_mm: Option<Vec<[f64; 2]>>,
}

impl HwSensor {
    /// The sensor's layout.
    pub fn layout(&self) -> SensorLayout {
        SensorLayout {
            name: self.name.clone(),
            model: self.model.clone(),
            finger: self.finger.clone(),
            rows: self.rows,
            cols: self.cols,
            taxel_positions_mm: self.taxel_positions_mm.clone(),
        }
    }

    /// Taxels read from the module.
    pub fn taxels(&self) -> usize {
        self.rows as usize * self.cols as usize
    }
}

/// The default sensors: modules 0, 1 and 2 on thumb, index and middle
/// finger, `rows x cols` taxels each.
pub fn default_sensors(rows: u32, cols: u32) -> Vec<HwSensor> {
    Finger::ALL
        .iter()
        .map(|f| HwSensor {
            name: f.name().into(),
            module: f.index() as u32,
            finger: f.name().into(),
            model: "uSkin".into(),
            rows,
            cols,
            taxel_positions_mm: None,
        })
        .collect()
}

/// Each finger reads taxel 0 of the sensor named after it.
pub fn default_fingers() -> PerFinger<FingerReading> {
    PerFinger::from_fn(|f| FingerReading::taxel(f.name(), 0))
}

/// What each finger reads: the `fingers` table when the config gives one,
/// else taxel 0 of the sensor whose `finger` key names the finger.
///
/// A gripper with two pads has sensors on `thumb` and `index` (or `middle`)
/// only: the finger without a sensor reads the same sensor as the other of
/// the two fingers that face the thumb, as the thesis's three-finger hand's
/// index and middle finger do. Two sensors on one finger, or no sensor on the
/// thumb, need the table.
pub fn finger_readings(
    sensors: &[HwSensor],
    table: Option<&PerFinger<FingerReading>>,
) -> Result<PerFinger<FingerReading>, SensorConfigError> {
    if let Some(table) = table {
        return Ok(table.clone());
    }
    let serving = |finger: Finger| -> Result<Option<&HwSensor>, SensorConfigError> {
        let mut on = sensors.iter().filter(|s| s.finger.eq_ignore_ascii_case(finger.name()));
        match (on.next(), on.next()) {
            (Some(first), Some(second)) => Err(SensorConfigError::SharedFinger {
                finger: finger.name(),
                first: first.name.clone(),
                second: second.name.clone(),
            }),
            (first, _) => Ok(first),
        }
    };
    let [thumb, index, middle] = [Finger::Thumb, Finger::Index, Finger::Middle].map(serving);
    let (thumb, index, middle) = (thumb?, index?, middle?);
    let no_sensor = |finger: Finger| SensorConfigError::NoSensorOnFinger {
        finger: finger.name(),
        fingers: sensors.iter().map(|s| format!("{} on {}", s.name, s.finger)).collect::<Vec<_>>().join(", "),
    };
    let thumb = thumb.ok_or_else(|| no_sensor(Finger::Thumb))?;
    let index = index.or(middle).ok_or_else(|| no_sensor(Finger::Index))?;
    let middle = middle.unwrap_or(index);
    let read = |s: &HwSensor| FingerReading::taxel(&s.name, 0);
    Ok(PerFinger { thumb: read(thumb), index: read(index), middle: read(middle) })
}

/// `(module, taxels)` of each sensor, for the serial scan assembler.
pub fn module_taxels(sensors: &[HwSensor]) -> Vec<(u32, usize)> {
    sensors.iter().map(|s| (s.module, s.taxels())).collect()
}

/// What a configured tactile device is: its sensors and, from the
/// `fingers` table or the sensors' `finger` keys ([`finger_readings`]), what
/// each finger reads. A table that [`validate_sensors`] rejects falls back to
/// [`default_fingers`], which the layout then refuses with its own message.
pub fn tactile_info(
    device: &str,
    rate_hz: f64,
    sensors: &[HwSensor],
    fingers: Option<&PerFinger<FingerReading>>,
) -> TactileInfo {
    TactileInfo {
        device: device.into(),
        rate_hz,
        layout: TactileLayout { sensors: sensors.iter().map(HwSensor::layout).collect() },
        fingers: finger_readings(sensors, fingers).unwrap_or_else(|_| default_fingers()),
    }
}

/// Checks the sensors and finger readings describe scans: unique names and
/// modules, at most `taxels_per_module` taxels per sensor, fingers that name
/// a sensor and one of its taxels.
pub fn validate_sensors(
    sensors: &[HwSensor],
    fingers: Option<&PerFinger<FingerReading>>,
    taxels_per_module: usize,
) -> Result<(), SensorConfigError> {
    for (i, s) in sensors.iter().enumerate() {
        if let Some(other) = sensors[..i].iter().find(|o| o.module == s.module) {
            return Err(SensorConfigError::SharedModule {
                module: s.module,
                first: other.name.clone(),
                second: s.name.clone(),
            });
        }
        if s.taxels() > taxels_per_module {
            return Err(SensorConfigError::TooManyTaxels {
                name: s.name.clone(),
                rows: s.rows,
                cols: s.cols,
                taxels_per_module,
            });
        }
    }
    let fingers = finger_readings(sensors, fingers)?;
    tactile_info("", 1.0, sensors, Some(&fingers)).finger_map()?;
    Ok(())
}

/// Sensors or finger readings that cannot describe scans.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum SensorConfigError {
    /// Two sensors on one module.
    #[error("hw.tactile.sensors `{first}` and `{second}` are both module {module}")]
    SharedModule {
        /// The module.
        module: u32,
        /// The first sensor.
        first: String,
        /// The second sensor.
        second: String,
    },
    /// A sensor with more taxels than its module sends.
    #[error(
        "hw.tactile.sensors `{name}` has {rows} x {cols} taxels, more than the {taxels_per_module} of a module (taxels_per_module)"
    )]
    TooManyTaxels {
        /// The sensor.
        name: String,
        /// Its rows.
        rows: u32,
        /// Its columns.
        cols: u32,
        /// Taxels a module sends.
        taxels_per_module: usize,
    },
    /// Two sensors name one finger and no `fingers` table says which reads it.
    #[error(
        "hw.tactile.sensors `{first}` and `{second}` are both on finger `{finger}`: say which one it reads in hw.tactile.fingers"
    )]
    SharedFinger {
        /// The finger.
        finger: &'static str,
        /// The first sensor on it.
        first: String,
        /// The second.
        second: String,
    },
    /// No sensor's `finger` key names a finger, and no `fingers` table.
    #[error(
        "no hw.tactile.sensors entry has finger = \"{finger}\" (sensors: {fingers}): set it, or give hw.tactile.fingers"
    )]
    NoSensorOnFinger {
        /// The finger.
        finger: &'static str,
        /// Each sensor with its finger, for the message.
        fingers: String,
    },
    /// A layout or finger reading that does not resolve.
    #[error("hw.tactile: {0}")]
    Layout(#[from] LayoutError),
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bad_sensor_tables_name_the_setting() {
        let fingers = Some(default_fingers());
        let fingers = fingers.as_ref();
        assert_eq!(validate_sensors(&default_sensors(4, 4), fingers, 16), Ok(()));
        let err = validate_sensors(&default_sensors(4, 6), fingers, 16).unwrap_err();
        assert_eq!(
            err.to_string(),
            "hw.tactile.sensors `thumb` has 4 x 6 taxels, more than the 16 of a module (taxels_per_module)"
        );
        let mut shared = default_sensors(4, 4);
        shared[2].module = 0;
        assert!(matches!(
            validate_sensors(&shared, fingers, 16),
            Err(SensorConfigError::SharedModule { .. })
        ));
        let mut far = default_fingers();
        far.index = FingerReading::taxel("index", 16);
        let err = validate_sensors(&default_sensors(4, 4), Some(&far), 16).unwrap_err();
        assert!(err.to_string().contains("finger `index` reads taxel 16 of tactile sensor `index`"), "{err}");
        let mut unknown = default_fingers();
        unknown.thumb = FingerReading::mean("left");
        let err = validate_sensors(&default_sensors(4, 4), Some(&unknown), 16).unwrap_err();
        assert!(err.to_string().contains("`left`, which the layout does not have"), "{err}");
    }

    /// A sensor on `finger` named `name`, 4 x 4 taxels on module `module`.
    fn on(name: &str, finger: &str, module: u32) -> HwSensor {
        HwSensor { name: name.into(), finger: finger.into(), module, ..default_sensors(4, 4)[0].clone() }
    }

    #[test]
    fn fingers_follow_the_sensors_finger_keys_without_a_table() {
        // The default table and the derived one agree on the default sensors
        // (each named after its finger): old configs read what they read.
        assert_eq!(finger_readings(&default_sensors(4, 4), None), Ok(default_fingers()));
        // Two pads named after their side: the pad facing the thumb serves
        // index and middle (the case `record` refused before the table).
        let pads = [on("left", "thumb", 1), on("right", "index", 2)];
        let read = finger_readings(&pads, None).unwrap();
        assert_eq!(read.thumb, FingerReading::taxel("left", 0));
        assert_eq!((read.index.clone(), read.middle.clone()), (FingerReading::taxel("right", 0), read.index));
        assert_eq!(validate_sensors(&pads, None, 16), Ok(()));
        // The same with the second pad on `middle`; the finger key ignores case.
        let read = finger_readings(&[on("l", "Thumb", 1), on("r", "middle", 2)], None).unwrap();
        assert_eq!((read.index, read.middle), (FingerReading::taxel("r", 0), FingerReading::taxel("r", 0)));
        // A table wins over the keys.
        let table = PerFinger::from_fn(|_| FingerReading::mean("right"));
        assert_eq!(finger_readings(&pads, Some(&table)), Ok(table));
    }

    #[test]
    fn ambiguous_or_missing_fingers_ask_for_the_table() {
        let two = [on("a", "thumb", 0), on("b", "thumb", 1), on("c", "index", 2)];
        let err = finger_readings(&two, None).unwrap_err();
        assert_eq!(
            err.to_string(),
            "hw.tactile.sensors `a` and `b` are both on finger `thumb`: say which one it reads in hw.tactile.fingers"
        );
        let sides = [on("a", "left", 0), on("b", "right", 1)];
        let err = validate_sensors(&sides, None, 16).unwrap_err();
        assert_eq!(
            err.to_string(),
            "no hw.tactile.sensors entry has finger = \"thumb\" (sensors: a on left, b on right): set it, or give hw.tactile.fingers"
        );
        let thumb_only = [on("a", "thumb", 0)];
        assert!(matches!(
            finger_readings(&thumb_only, None),
            Err(SensorConfigError::NoSensorOnFinger { finger: "index", .. })
        ));
    }
}
