//! The calibration file: versioned TOML, one map per taxel of every sensor.

use std::path::Path;

use serde::{Deserialize, Serialize};
use slidetrack_core::TactileLayout;

use super::error::TactileForceError;
use super::features::{ForceModelKind, TaxelForceMap};

/// The `format` every calibration file names.
pub const FORMAT: &str = "slidetrack.tactile_force_calibration";

/// The version of [`FORMAT`] this build writes and reads.
pub const VERSION: u32 = 1;

/// A rig's tactile force calibration, as stored beside its rig TOML and
/// named there by `tactile_calibration`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TactileForceCalibration {
    /// Always [`FORMAT`].
    pub format: String,
    /// Always [`VERSION`].
    pub version: u32,
    /// The terms of every taxel's map.
    pub model: ForceModelKind,
    /// How counts are zeroed before the map (the protocol's tare: the mean
    /// of the open-hand scans subtracted, per taxel and axis).
    pub baseline: String,
    /// What the maps were fitted against.
    pub reference: String,
    /// The sessions the maps were fitted on.
    pub fitted_on: Vec<String>,
    /// RMS error per axis `[x, y, z]` on the scans fitted on (N).
    pub fit_rms_n: [f64; 3],
    /// Range of the reference per axis on the scans fitted on (N).
    pub fit_range_n: [f64; 3],
    /// One entry per tactile sensor, in the rig's layout order.
    pub sensors: Vec<SensorForceMap>,
}

/// The maps of one sensor's taxels.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SensorForceMap {
    /// The sensor's name in the tactile layout.
    pub name: String,
    /// One map per taxel, row by row as in `/tactile/raw`.
    pub taxels: Vec<TaxelForceMap>,
}

impl TactileForceCalibration {
    /// Reads and checks a calibration file.
    pub fn load(path: &Path) -> Result<TactileForceCalibration, TactileForceError> {
        let text = std::fs::read_to_string(path)
            .map_err(|source| TactileForceError::Io { path: path.to_path_buf(), source })?;
        let cal: TactileForceCalibration = toml::from_str(&text).map_err(|e| {
            // One line: the message and where, without the source excerpt.
            let line = e.span().map_or(1, |s| text[..s.start.min(text.len())].matches('\n').count() + 1);
            TactileForceError::Parse {
                path: path.to_path_buf(),
                detail: format!("line {line}: {}", e.message()),
            }
        })?;
        if cal.format != FORMAT || cal.version != VERSION {
            return Err(TactileForceError::Version {
                path: path.to_path_buf(),
                format: cal.format,
                version: cal.version,
                expected_format: FORMAT,
                expected_version: VERSION,
            });
        }
        cal.check_taxels()?;
        Ok(cal)
    }

    /// Writes the calibration as TOML.
    pub fn save(&self, path: &Path) -> Result<(), TactileForceError> {
        let text = toml::to_string(self)
            .map_err(|e| TactileForceError::Parse { path: path.to_path_buf(), detail: e.to_string() })?;
        std::fs::write(path, text)
            .map_err(|source| TactileForceError::Io { path: path.to_path_buf(), source })
    }

    /// Every taxel's map is of the file's model and finite.
    fn check_taxels(&self) -> Result<(), TactileForceError> {
        for sensor in &self.sensors {
            for (k, taxel) in sensor.taxels.iter().enumerate() {
                let bad = |detail: String| TactileForceError::BadTaxel {
                    sensor: sensor.name.clone(),
                    taxel: k,
                    detail,
                };
                if taxel.kind() != self.model {
                    return Err(bad(format!(
                        "a {} map in a {} calibration",
                        taxel.kind().name(),
                        self.model.name()
                    )));
                }
                if !taxel.is_finite() {
                    return Err(bad("a coefficient is not finite".into()));
                }
            }
        }
        Ok(())
    }

    /// Checks that the calibration has a map for every taxel of `layout`,
    /// sensor by sensor in the same order and with the same names.
    pub fn check_layout(&self, layout: &TactileLayout) -> Result<(), TactileForceError> {
        let names = |v: Vec<&str>| v.join(", ");
        if self.sensors.len() != layout.sensors.len() {
            return Err(TactileForceError::Layout {
                detail: format!(
                    "it has sensors [{}], the rig [{}]",
                    names(self.sensors.iter().map(|s| s.name.as_str()).collect()),
                    names(layout.sensors.iter().map(|s| s.name.as_str()).collect())
                ),
            });
        }
        for (cal, sensor) in self.sensors.iter().zip(&layout.sensors) {
            if cal.name != sensor.name || cal.taxels.len() != sensor.taxels() {
                return Err(TactileForceError::Layout {
                    detail: format!(
                        "it has sensor {:?} with {} taxels where the rig has {:?} with {}",
                        cal.name,
                        cal.taxels.len(),
                        sensor.name,
                        sensor.taxels()
                    ),
                });
            }
        }
        Ok(())
    }

    /// The force on every taxel (N, in each taxel's frame) from one scan of
    /// tared counts in layout order (checked by [`Self::check_layout`]);
    /// taxels beyond the calibration get zero.
    pub fn forces_n(&self, zeroed: &[[f64; 3]]) -> Vec<[f64; 3]> {
        let maps = self.sensors.iter().flat_map(|s| &s.taxels);
        let mut out: Vec<[f64; 3]> = maps.zip(zeroed).map(|(m, c)| m.force_n(*c)).collect();
        out.resize(zeroed.len(), [0.0; 3]);
        out
    }
}
