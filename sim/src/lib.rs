#![doc = include_str!("../README.md")]
#![warn(missing_docs)]

mod board_camera;
pub mod camera;
mod camera_device;
mod config;
mod episodes;
mod finger;
mod friction;
mod gripper;
mod gripper_device;
mod object;
pub mod rgbd;
mod rig;
mod shared_world;
mod surface;
mod tactile_model;
mod world;

pub use board_camera::SimBoardCamera;
pub use camera_device::{FrameEncoder, SimCamera};
pub use config::SimRigConfig;
pub use episodes::{Episode, sliding_episodes};
pub use finger::{FingerConfig, FingerState};
pub use friction::{LuGreContact, LuGreParams};
pub use gripper::{GripperConfig, GripperState, HandKind};
pub use gripper_device::SimGripper;
pub use object::{
    BUILTIN_OBJECTS, ExperimentSettings, FrictionConfig, ObjectConfig, ObjectGeometry, TrialJitter,
};
pub use rig::{
    SharedWorld, SimActuator, SimDevices, SimHand, SimHandMonitor, SimTactile, SimTruthTap, sim_tactile_info,
};
pub use surface::{SurfaceConfig, SurfaceProfile};
pub use tactile_model::{ContactDeformation, PatchConfig, TactileModelConfig, TactileModule};
pub use world::{SimWorld, Stream, stream_seed};

use thiserror::Error;

/// Errors in setting up the simulated rig.
#[derive(Debug, Error)]
pub enum SimError {
    /// No built-in object has this name and it is not a `.toml` path.
    #[error("unknown object '{name}' (built-in objects: {}; or give a path to an object .toml)", known.join(", "))]
    UnknownObject {
        /// The name asked for.
        name: String,
        /// The built-in names.
        known: Vec<String>,
    },
    /// A configuration could not be parsed.
    #[error(transparent)]
    Parse(#[from] slidetrack_core::ConfigError),
    /// A configuration could not be read or is invalid.
    #[error("{origin}: {detail}")]
    BadConfig {
        /// File or source of the configuration.
        origin: String,
        /// What is wrong.
        detail: String,
    },
}
