//! The devices as the commands see them: what is plugged in (`slidetrack
//! devices`), the tactile tables and captured-traffic decoders of
//! `slidetrack decode`, and the Robotiq emulator of `slidetrack emulate
//! robotiq`. The drivers crate stays behind this module.

pub use slidetrack_drivers::can::log::CanLogDecoder;
pub use slidetrack_drivers::config::{CanTactileConfig, HwRigConfig, SerialTactileConfig, TactileDevice};
#[cfg(all(feature = "devices", target_os = "linux"))]
pub use slidetrack_drivers::devices::{
    CameraListing, CanListing, DeviceList, FormatListing, SerialPortListing, SizeListing, list_devices,
};
pub use slidetrack_drivers::robotiq::RobotiqModel;
#[cfg(all(feature = "devices", target_os = "linux"))]
pub use slidetrack_drivers::robotiq::backend::{RobotiqEmulator, RobotiqEmulatorOptions};
pub use slidetrack_drivers::sensors::tactile_info;
pub use slidetrack_drivers::serial::capture::SerialCaptureDecoder;
