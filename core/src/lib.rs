#![doc = include_str!("../README.md")]
#![warn(missing_docs)]

mod board;
mod camera;
mod config;
mod counters;
mod error;
mod hand;
mod image;
mod marker;
mod phase;
mod placement;
pub mod rgbd;
mod tactile;
mod time;
mod truth;

pub use board::{BadBoardLayout, BoardLayout, BoardMarker};
pub use camera::{Camera, CameraIntrinsics, Frame};
pub use config::{ConfigError, parse_toml};
pub use counters::DecoderCounters;
pub use error::{DeviceError, ErrorKind};
pub use hand::{
    ActuatorCommand, ActuatorSpec, FingerVolts, GripperObject, GripperRequest, GripperSpec, GripperStatus,
    HandActuator, HandMonitor, HandStatus, saturate,
};
pub use image::{EncodedImage, Image, JpegError, PixelFormat, encode_jpeg};
pub use marker::{BadMarkerPattern, MarkerPattern};
pub use phase::Phase;
pub use placement::{CameraPlacement, PlacementError};
pub use rgbd::{DepthImage, ObjectTruth, RgbdFrame};
pub use tactile::{
    AXES, Finger, FingerMap, FingerReading, LayoutError, PerFinger, RawTaxel, SensorLayout, TactileInfo,
    TactileLayout, TactileSample, TactileSource,
};
pub use time::{Clock, SimClock, TimeNs, WallClock};
pub use truth::{SLIDING_SPEED_MPS, SimTruth, TruthSource};
