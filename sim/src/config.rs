//! Settings of the simulated rig (the `[sim]` table of a rig TOML).

use serde::{Deserialize, Serialize};

use super::SimError;
use super::finger::FingerConfig;
use super::gripper::{GripperConfig, HandKind};
use super::object::ObjectConfig;
use super::tactile_model::TactileModelConfig;

/// The simulated hand and sensors. Every field has a default; a rig TOML
/// overrides what it names.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SimRigConfig {
    /// The hand: `three_finger` (the thesis's hand, the default) or `gripper`.
    #[serde(skip_serializing_if = "HandKind::is_three_finger")]
    pub hand: HandKind,
    /// The parallel gripper, when `hand = "gripper"`.
    #[serde(skip_serializing_if = "SimRigConfig::is_default_gripper")]
    pub gripper: GripperConfig,
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
    /// Give every tactile scan the force on each taxel (N) as its reference
    /// (`/tactile/reference`), to fit `slidetrack calibrate tactile` on.
    /// Off by default: sessions without it are as before, byte for byte.
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub reference_forces: bool,
}

impl Default for SimRigConfig {
    fn default() -> Self {
        SimRigConfig {
            hand: HandKind::ThreeFinger,
            gripper: GripperConfig::default(),
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
            reference_forces: false,
        }
    }
}

impl SimRigConfig {
    fn is_default_gripper(gripper: &GripperConfig) -> bool {
        *gripper == GripperConfig::default()
    }

    /// Checks values that TOML types cannot (the gripper's): the error names
    /// the field.
    pub fn validate(&self) -> Result<(), SimError> {
        match self.gripper.invalid_field() {
            Some((field, detail)) => {
                Err(SimError::BadConfig { origin: format!("sim.gripper.{field}"), detail })
            }
            None => Ok(()),
        }
    }

    /// Checks that `object` fits the hand: a gripper must open wider than
    /// the object unless `[sim.gripper] contact_opening_m` says where the
    /// pads touch it.
    pub fn check_object(&self, object: &ObjectConfig) -> Result<(), SimError> {
        let width = object.geometry.width_m;
        if self.hand == HandKind::Gripper
            && self.gripper.contact_opening_m.is_none()
            && width >= self.gripper.stroke_m
        {
            return Err(SimError::BadConfig {
                origin: "sim.gripper.stroke_m".into(),
                detail: format!(
                    "the gripper opens {} m, less than the width of object '{}' ({width} m)",
                    self.gripper.stroke_m, object.name
                ),
            });
        }
        Ok(())
    }

    /// Where the gripper's pads touch `object`: the opening (m).
    pub fn contact_opening_m(&self, object: &ObjectConfig) -> f64 {
        self.gripper.contact_opening_m.unwrap_or(object.geometry.width_m)
    }

    /// The finger at `index` of [`slidetrack_core::Finger::ALL`].
    pub fn finger(&self, index: usize) -> &FingerConfig {
        match index {
            0 => &self.thumb,
            1 => &self.index,
            _ => &self.middle,
        }
    }
}
