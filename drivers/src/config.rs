//! The `[hw]` table of a rig TOML: which device backs each role on the real rig.
//!
//! ```toml
//! [hw]
//! name = "lab-hand"
//! [hw.tactile]
//! kind = "serial"            # or "can", "xela_ws" (see `crate::xela_ws::config`), "ros2" (`crate::xela_ros2`), or "sim"
//! port = "/dev/ttyACM0"      # "emulated": the simulated rig behind a pseudo-terminal
//! taxels_per_module = 16
//! # [[hw.tactile.sensors]] tables (see `crate::sensors`) name each module;
//! # by default modules 0, 1, 2 are 4 x 4 patches on thumb, index, middle.
//! fingers = { thumb = { sensor = "thumb", taxel = 5 }, index = { sensor = "index", taxel = 5 }, middle = { sensor = "middle" } }
//! [hw.camera]
//! kind = "v4l2"              # or "sim", "none", or "rgbd" (the `[rgbd]` camera, see `crate::rgbd_config`)
//! device = "/dev/video0"
//! [hw.hand]
//! kind = "can"               # or "sim", or "robotiq" (see `crate::robotiq::config`)
//! interface = "can0"
//! ```

use serde::{Deserialize, Serialize};

pub use crate::can::config::CanTactileConfig;
pub use crate::can_hand::config::CanHandConfig;
pub use crate::emulated::EMULATED_PORT;
pub use crate::robotiq::config::{RobotiqConfig, RobotiqConfigError, RobotiqEmulatorConfig, RobotiqModel};
pub use crate::serial::config::{EmulatorConfig, SerialTactileConfig};
pub use crate::slcan::config::SlcanTransport;
pub use crate::tactile::TactileDevice;
pub use crate::v4l2::config::{V4l2CameraConfig, V4l2PixelFormat};
pub use error::{HwConfigError, IdCollision};

pub mod error;

/// The devices of the real rig. Every role defaults to its simulated device.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct HwRigConfig {
    /// Name of the rig, recorded in the session metadata.
    pub name: String,
    /// The fingertip sensors.
    pub tactile: TactileDevice,
    /// The camera that sees the marker.
    pub camera: CameraDevice,
    /// The hand actuator.
    pub hand: HandDevice,
}

impl Default for HwRigConfig {
    fn default() -> Self {
        HwRigConfig {
            name: "hw".into(),
            tactile: TactileDevice::Sim,
            camera: CameraDevice::Sim,
            hand: HandDevice::Sim,
        }
    }
}

/// The camera that sees the marker.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "lowercase")]
pub enum CameraDevice {
    /// No camera.
    None,
    /// The simulated camera (`[camera]` table).
    Sim,
    /// A V4L2 camera.
    V4l2(Box<V4l2CameraConfig>),
    /// The RGB-D camera of the rig's `[rgbd]` table: its colour frames feed
    /// the marker's detection too, and its colour, depth and calibration
    /// are recorded (one camera for every use).
    Rgbd(RgbdMarkerCamera),
}

/// `[hw.camera] kind = "rgbd"`: the `[rgbd]` camera sees the marker. Its
/// device, intrinsics and registration are those of the `[rgbd]` table.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RgbdMarkerCamera {
    /// Where the colour camera is in the hand frame.
    pub placement: slidetrack_core::CameraPlacement,
}

/// The hand actuator.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "lowercase")]
pub enum HandDevice {
    /// The simulated hand (`[sim]` table).
    Sim,
    /// The hand on CAN.
    Can(CanHandConfig),
    /// A Robotiq 2F-85/2F-140/Hand-E gripper on Modbus RTU.
    Robotiq(RobotiqConfig),
}

impl HwRigConfig {
    /// Checks what serde's types cannot.
    pub fn validate(&self) -> Result<(), HwConfigError> {
        self.tactile.validate()?;
        if let CameraDevice::V4l2(v) = &self.camera {
            v.validate()?;
        }
        if let HandDevice::Robotiq(r) = &self.hand {
            r.validate()?;
        }
        if let HandDevice::Can(h) = &self.hand {
            h.validate()?;
            if let Some(collision) = self.tactile.can_collision_with_hand(&h.interface, &h.ids()) {
                return Err(collision.into());
            }
        }
        Ok(())
    }

    /// Nominal tactile scan rate of the configured device (Hz), `sim_rate_hz`
    /// for the simulated and emulated sensors.
    pub fn tactile_rate_hz(&self, sim_rate_hz: f64) -> f64 {
        self.tactile.rate_hz(sim_rate_hz)
    }
}

#[cfg(test)]
mod tests;
