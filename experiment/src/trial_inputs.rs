//! The object and the rig a new trial runs with, loaded from their names or
//! files (`collect`, `record`, `bench`), and the simulator's built-in objects.

use std::path::Path;

use anyhow::Result;
use slidetrack_sim::{BUILTIN_OBJECTS, ObjectConfig};

use crate::rig_config::RigConfig;

/// The object and the rig of new trials.
pub struct TrialInputs {
    /// The object: its geometry, mass, friction and the experiment's settings.
    pub object: ObjectConfig,
    /// The rig: its geometry, camera and devices.
    pub rig: RigConfig,
}

impl TrialInputs {
    /// Loads `object` (a built-in name or an object TOML) and the rig TOML
    /// `config` (the built-in simulated rig when `None`).
    pub fn load(object: &str, config: Option<&Path>) -> Result<TrialInputs> {
        let object = ObjectConfig::load(object)?;
        let rig = RigConfig::load(config)?;
        Ok(TrialInputs { object, rig })
    }
}

/// The simulator's built-in objects, in their listed order.
pub fn builtin_objects() -> Result<Vec<ObjectConfig>> {
    BUILTIN_OBJECTS.iter().map(|(name, _)| Ok(ObjectConfig::load(name)?)).collect()
}
