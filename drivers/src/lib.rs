#![doc = include_str!("../README.md")]
#![warn(missing_docs)]

mod camera;
mod config;
mod error;
mod hand;
mod image;
mod tactile;
mod time;

pub use camera::{Camera, CameraIntrinsics, Frame};
pub use config::{ConfigError, parse_toml};
pub use error::{DeviceError, ErrorKind};
pub use hand::{FingerVolts, HandActuator, saturate};
pub use hw::DecoderCounters;
pub use image::{EncodedImage, Image, PixelFormat};
pub use tactile::{AXES, Finger, RawTaxel, TactileInfo, TactileSample, TactileSource};
pub use time::{Clock, SimClock, TimeNs, WallClock};

pub mod hw;
pub mod session;
pub mod sim;
