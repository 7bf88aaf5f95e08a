//! Settings of the simulated rig (the `[sim]` table of a rig TOML).

use serde::{Deserialize, Serialize};

use super::finger::FingerConfig;
use super::tactile_model::TactileModelConfig;

/// The simulated hand and sensors. Every field has a default; a rig TOML
/// overrides what it names.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SimRigConfig {
    /// Fixed physics step rate (Hz).
    pub physics_rate_hz: f64,
    /// Tactile scan rate (Hz).
    pub tactile_rate_hz: f64,
    /// Gravity along the sliding axis (m/s^2).
    pub gravity_mps2: f64,
    /// Largest proximal-joint voltage magnitude (V).
    pub max_volts: f64,
    /// The arm lifts the object once the static friction capacity of the grasp
    /// exceeds its weight by this factor...
    pub lift_margin: f64,
    /// ...for this long (s).
    pub lift_hold_s: f64,
    /// The thumb.
    pub thumb: FingerConfig,
    /// The index finger.
    pub index: FingerConfig,
    /// The middle finger.
    pub middle: FingerConfig,
    /// The tactile modules.
    pub tactile: TactileModelConfig,
}

impl Default for SimRigConfig {
    fn default() -> Self {
        SimRigConfig {
            physics_rate_hz: 2000.0,
            tactile_rate_hz: 100.0,
            gravity_mps2: 9.81,
            max_volts: 10.0,
            lift_margin: 1.4,
            lift_hold_s: 0.3,
            thumb: FingerConfig::default(),
            index: FingerConfig::default(),
            middle: FingerConfig::default(),
            tactile: TactileModelConfig::default(),
        }
    }
}

impl SimRigConfig {
    /// The finger at `index` of [`slidetrack_core::Finger::ALL`].
    pub fn finger(&self, index: usize) -> &FingerConfig {
        match index {
            0 => &self.thumb,
            1 => &self.index,
            _ => &self.middle,
        }
    }
}
