//! What is wrong with a `[hw]` table: one error type for every device's
//! checks, so that each transport's configuration validates itself.

use thiserror::Error;

use crate::can::layout::CanMapError;
use crate::can::protocol::CanLayoutError;
use crate::can_hand::protocol::HandFrameError;
use crate::robotiq::config::RobotiqConfigError;
use crate::sensors::SensorConfigError;
use crate::xela_ws::config::XelaConfigError;

/// A `[hw]` table with values that cannot work.
#[derive(Clone, Debug, Error, PartialEq)]
pub enum HwConfigError {
    /// A setting that cannot work for a reason other than its range (a
    /// transport's own checks).
    #[error("hw.{field}: {reason}")]
    Invalid {
        /// The setting, as in the file (`tactile.url`).
        field: String,
        /// Why it cannot work.
        reason: String,
    },
    /// A number outside its range.
    #[error("hw.{field} = {value} is out of range ({expected})")]
    OutOfRange {
        /// The setting, as in the file.
        field: String,
        /// Its value.
        value: f64,
        /// The valid range, in words.
        expected: &'static str,
    },
    /// Sensors or finger readings that do not fit the device.
    #[error(transparent)]
    Sensors(#[from] SensorConfigError),
    /// A sensor beyond the CAN board's taxels.
    #[error(
        "hw.tactile.sensors `{name}` (module {module}) ends at board taxel {end}, beyond the board's {taxels} taxels"
    )]
    BeyondBoard {
        /// The sensor.
        name: String,
        /// Its module.
        module: u32,
        /// One past its last board taxel.
        end: usize,
        /// Taxels of the board.
        taxels: u16,
    },
    /// A `kind = "xela_ws"` table that cannot work.
    #[error(transparent)]
    XelaWs(#[from] XelaConfigError),
    /// Bad CAN ids of the tactile board.
    #[error("hw.tactile: {0}")]
    CanLayout(#[from] CanLayoutError),
    /// A CAN layout that does not describe the sensors.
    #[error("{0}")]
    CanMap(#[from] CanMapError),
    /// Tactile and hand ids on one bus.
    #[error("{0}")]
    IdCollision(#[from] IdCollision),
    /// Another CAN setting out of range.
    #[error("{0}")]
    Can(String),
    /// Bad CAN ids of the hand.
    #[error("hw.hand: {0}")]
    HandIds(#[from] HandFrameError),
    /// A `kind = "robotiq"` hand that cannot work.
    #[error(transparent)]
    Robotiq(#[from] RobotiqConfigError),
    /// A V4L2 camera with neither a calibration file nor inline intrinsics,
    /// or inline intrinsics of another size.
    #[error("hw.camera: {0}")]
    Camera(String),
}

/// `Ok` when `ok`, else [`HwConfigError::OutOfRange`] naming `hw.{field}`.
pub(crate) fn check(field: &str, value: f64, ok: bool, expected: &'static str) -> Result<(), HwConfigError> {
    if ok { Ok(()) } else { Err(HwConfigError::OutOfRange { field: field.into(), value, expected }) }
}

/// One CAN id used by both the tactile source and the hand on one bus.
#[derive(Clone, Debug, Error, PartialEq, Eq)]
#[error("{tactile_key} and {hand_key} both use CAN id 0x{id:X} on {interface}: give one of them another id")]
pub struct IdCollision {
    /// The tactile setting.
    pub tactile_key: String,
    /// The hand setting.
    pub hand_key: String,
    /// The id.
    pub id: u32,
    /// The shared interface.
    pub interface: String,
}
