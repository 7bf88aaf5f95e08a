//! The tactile sensors of a real rig as configured (`[[hw.tactile.sensors]]`):
//! which module on the bus each sensor is, its layout, and the finger
//! readings (`hw.tactile.fingers`).
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

/// `(module, taxels)` of each sensor, for the serial scan assembler.
pub fn module_taxels(sensors: &[HwSensor]) -> Vec<(u32, usize)> {
    sensors.iter().map(|s| (s.module, s.taxels())).collect()
}

/// What a configured tactile device is.
pub fn tactile_info(
    device: &str,
    rate_hz: f64,
    sensors: &[HwSensor],
    fingers: &PerFinger<FingerReading>,
) -> TactileInfo {
    TactileInfo {
        device: device.into(),
        rate_hz,
        layout: TactileLayout { sensors: sensors.iter().map(HwSensor::layout).collect() },
        fingers: fingers.clone(),
    }
}

/// Checks the sensors and finger readings describe scans: unique names and
/// modules, at most `taxels_per_module` taxels per sensor, fingers that name
/// a sensor and one of its taxels.
pub fn validate_sensors(
    sensors: &[HwSensor],
    fingers: &PerFinger<FingerReading>,
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
    tactile_info("", 1.0, sensors, fingers).finger_map()?;
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
    /// A layout or finger reading that does not resolve.
    #[error("hw.tactile: {0}")]
    Layout(#[from] LayoutError),
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bad_sensor_tables_name_the_setting() {
        let fingers = default_fingers();
        assert_eq!(validate_sensors(&default_sensors(4, 4), &fingers, 16), Ok(()));
        let err = validate_sensors(&default_sensors(4, 6), &fingers, 16).unwrap_err();
        assert_eq!(
            err.to_string(),
            "hw.tactile.sensors `thumb` has 4 x 6 taxels, more than the 16 of a module (taxels_per_module)"
        );
        let mut shared = default_sensors(4, 4);
        shared[2].module = 0;
        assert!(matches!(
            validate_sensors(&shared, &fingers, 16),
            Err(SensorConfigError::SharedModule { .. })
        ));
        let mut far = default_fingers();
        far.index = FingerReading::taxel("index", 16);
        let err = validate_sensors(&default_sensors(4, 4), &far, 16).unwrap_err();
        assert!(err.to_string().contains("finger `index` reads taxel 16 of tactile sensor `index`"), "{err}");
        let mut unknown = default_fingers();
        unknown.thumb = FingerReading::mean("left");
        let err = validate_sensors(&default_sensors(4, 4), &unknown, 16).unwrap_err();
        assert!(err.to_string().contains("`left`, which the layout does not have"), "{err}");
    }
}
