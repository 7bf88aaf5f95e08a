//! The `[hw]` table of a rig TOML: which device backs each role on the real rig.
//!
//! ```toml
//! [hw]
//! name = "lab-hand"
//! [hw.tactile]
//! kind = "serial"            # or "can", "xela_ws" (see `crate::xela_ws::config`), or "sim"
//! port = "/dev/ttyACM0"      # "emulated": the simulated rig behind a pseudo-terminal
//! taxels_per_module = 16
//! # [[hw.tactile.sensors]] tables (see `crate::sensors`) name each module;
//! # by default modules 0, 1, 2 are 4 x 4 patches on thumb, index, middle.
//! fingers = { thumb = { sensor = "thumb", taxel = 5 }, index = { sensor = "index", taxel = 5 }, middle = { sensor = "middle" } }
//! [hw.camera]
//! kind = "v4l2"              # or "sim", or "none"
//! device = "/dev/video0"
//! [hw.hand]
//! kind = "can"               # or "sim", or "robotiq" (see `crate::robotiq::config`)
//! interface = "can0"
//! ```

use std::path::PathBuf;

use serde::{Deserialize, Serialize};
use slidetrack_core::{CameraIntrinsics, CameraPlacement, FingerReading, PerFinger};
use thiserror::Error;

pub use crate::can_config::{CanTactileConfig, IdCollision, SlcanTransport};
use crate::can_layout::CanMapError;
use crate::can_protocol::CanLayoutError;
use crate::hand_can::{HandCanIds, HandFrameError};
pub use crate::robotiq::config::{RobotiqConfig, RobotiqConfigError, RobotiqEmulatorConfig, RobotiqModel};
use crate::sensors::{HwSensor, SensorConfigError, default_fingers, default_sensors, validate_sensors};
use crate::serial_protocol::MAX_TAXELS;
use crate::xela_ws::config::{EMULATED_URL, XelaConfigError, XelaWsTactileConfig};

/// The port name that selects the serial emulator instead of a device.
pub const EMULATED_PORT: &str = "emulated";

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

/// The fingertip sensors.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "lowercase")]
pub enum TactileDevice {
    /// The simulated modules (`[sim]` table), on the wall clock.
    Sim,
    /// uSkin-style modules streaming the serial format.
    Serial(SerialTactileConfig),
    /// Taxel frames on CAN (SocketCAN or an SLCAN adapter), in a
    /// configured layout.
    Can(CanTactileConfig),
    /// XELA sensors read through XELA's `xela_server` (WebSocket JSON).
    #[serde(rename = "xela_ws")]
    XelaWs(XelaWsTactileConfig),
}

/// uSkin-style modules on a serial port.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SerialTactileConfig {
    /// Device path (`/dev/ttyACM0`), or `emulated` for the simulated rig
    /// streaming the same bytes through a pseudo-terminal.
    pub port: String,
    /// Baud rate (ignored by USB CDC devices and pseudo-terminals).
    pub baud: u32,
    /// Nominal scan rate (Hz), recorded in the taxel layout. The emulator
    /// runs at the `[sim]` tactile rate instead.
    pub rate_hz: f64,
    /// Taxels in each module's frame.
    pub taxels_per_module: u16,
    /// Longest wait for a scan once streaming (ms).
    pub timeout_ms: u64,
    /// Longest wait for the first scan after opening the port (ms).
    pub startup_timeout_ms: u64,
    /// The sensors: which modules are read, their layout and finger.
    pub sensors: Vec<HwSensor>,
    /// What each finger's reading is (a taxel of a sensor, or its mean).
    pub fingers: PerFinger<FingerReading>,
    /// Faults the emulator injects (only with `port = "emulated"`).
    pub emulator: EmulatorConfig,
}

impl Default for SerialTactileConfig {
    fn default() -> Self {
        SerialTactileConfig {
            port: "/dev/ttyACM0".into(),
            baud: 921_600,
            rate_hz: 100.0,
            taxels_per_module: 16,
            timeout_ms: 50,
            startup_timeout_ms: 2000,
            sensors: default_sensors(4, 4),
            fingers: default_fingers(),
            emulator: EmulatorConfig::default(),
        }
    }
}

/// Faults the serial emulator injects, for tests and demonstrations.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct EmulatorConfig {
    /// Close the pseudo-terminal (as if the device were unplugged) this long
    /// after the first scan (s).
    pub unplug_after_s: Option<f64>,
    /// Flip a payload bit in every n-th frame (0: never).
    pub corrupt_every_frames: u32,
    /// Insert a few bytes of garbage before every n-th frame (0: never).
    pub garbage_every_frames: u32,
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
}

/// Pixel formats slidetrack streams from V4L2 cameras (the names of the
/// kernel's pixel format documentation; lower case is accepted too).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum V4l2PixelFormat {
    /// Motion JPEG: recorded as it comes, decoded for detection.
    #[serde(rename = "MJPG", alias = "mjpg")]
    Mjpg,
    /// YUV 4:2:2: the luma drives detection, frames are JPEG-encoded for the session.
    #[serde(rename = "YUYV", alias = "yuyv")]
    Yuyv,
    /// 8-bit gray (`V4L2_PIX_FMT_GREY`, also called Y8): the pixels drive
    /// detection, frames are JPEG-encoded for the session.
    #[serde(rename = "GREY", alias = "grey", alias = "Y8", alias = "y8")]
    Grey,
    /// 16-bit depth of RGB-D cameras (`V4L2_PIX_FMT_Z16`, little-endian):
    /// recorded as 16-bit PNG, no detection.
    #[serde(rename = "Z16", alias = "z16")]
    Z16,
}

impl V4l2PixelFormat {
    /// The V4L2 fourcc code.
    pub fn fourcc(self) -> [u8; 4] {
        match self {
            V4l2PixelFormat::Mjpg => *b"MJPG",
            V4l2PixelFormat::Yuyv => *b"YUYV",
            V4l2PixelFormat::Grey => *b"GREY",
            V4l2PixelFormat::Z16 => *b"Z16 ",
        }
    }

    /// Bytes per pixel of the uncompressed formats; `None` for MJPG.
    pub fn bytes_per_pixel(self) -> Option<u32> {
        match self {
            V4l2PixelFormat::Mjpg => None,
            V4l2PixelFormat::Grey => Some(1),
            V4l2PixelFormat::Yuyv | V4l2PixelFormat::Z16 => Some(2),
        }
    }
}

/// A V4L2 camera.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct V4l2CameraConfig {
    /// Device node.
    pub device: String,
    /// Frame width (px).
    pub width: u32,
    /// Frame height (px).
    pub height: u32,
    /// Pixel format to stream.
    pub pixel_format: V4l2PixelFormat,
    /// Frame rate to ask for (Hz).
    pub fps: f64,
    /// Memory-mapped buffers.
    pub buffers: u32,
    /// Longest wait for a frame before the camera counts as gone (ms).
    pub timeout_ms: u64,
    /// Longest wait for the first frame after streaming starts (ms): cameras
    /// take longer to deliver their first frame (auto-exposure, a depth
    /// camera's laser) than between frames.
    pub startup_timeout_ms: u64,
    /// JPEG quality for formats recorded re-encoded (YUYV), 1-100.
    pub jpeg_quality: u8,
    /// Camera calibration file: ROS `camera_info` or OpenCV YAML, or TOML
    /// with the fields of `intrinsics`.
    pub calibration: Option<PathBuf>,
    /// Intrinsics given inline, when there is no calibration file.
    pub intrinsics: Option<CameraIntrinsics>,
    /// Where the camera is in the hand frame.
    pub placement: CameraPlacement,
}

impl Default for V4l2CameraConfig {
    fn default() -> Self {
        V4l2CameraConfig {
            device: "/dev/video0".into(),
            width: 640,
            height: 480,
            pixel_format: V4l2PixelFormat::Mjpg,
            fps: 30.0,
            buffers: 4,
            timeout_ms: 1000,
            startup_timeout_ms: 5000,
            jpeg_quality: 90,
            calibration: None,
            intrinsics: None,
            placement: CameraPlacement::default(),
        }
    }
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

/// The hand on CAN.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CanHandConfig {
    /// SocketCAN interface.
    pub interface: String,
    /// Id of the set-point frame.
    pub setpoint_id: u32,
    /// Id of the heartbeat frame.
    pub heartbeat_id: u32,
    /// Id of the release frame.
    pub release_id: u32,
    /// Heartbeat period (ms); the hand opens by itself after three missed.
    pub heartbeat_ms: u64,
    /// Largest voltage magnitude sent (V).
    pub max_volts: f64,
}

impl Default for CanHandConfig {
    fn default() -> Self {
        let ids = HandCanIds::default();
        CanHandConfig {
            interface: "can0".into(),
            setpoint_id: ids.setpoint_id,
            heartbeat_id: ids.heartbeat_id,
            release_id: ids.release_id,
            heartbeat_ms: 20,
            max_volts: 10.0,
        }
    }
}

impl CanHandConfig {
    /// The frame ids.
    pub fn ids(&self) -> HandCanIds {
        HandCanIds {
            setpoint_id: self.setpoint_id,
            heartbeat_id: self.heartbeat_id,
            release_id: self.release_id,
        }
    }
}

/// A `[hw]` table with values that cannot work.
#[derive(Clone, Debug, Error, PartialEq)]
pub enum HwConfigError {
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

fn check(field: &str, value: f64, ok: bool, expected: &'static str) -> Result<(), HwConfigError> {
    if ok { Ok(()) } else { Err(HwConfigError::OutOfRange { field: field.into(), value, expected }) }
}

/// The checks of a serial tactile device that serde's types cannot make.
fn validate_serial(s: &SerialTactileConfig) -> Result<(), HwConfigError> {
    check("tactile.rate_hz", s.rate_hz, s.rate_hz.is_finite() && s.rate_hz > 0.0, "> 0 Hz")?;
    let n = f64::from(s.taxels_per_module);
    let ok = (1..=MAX_TAXELS).contains(&usize::from(s.taxels_per_module));
    check("tactile.taxels_per_module", n, ok, "1..=64")?;
    check("tactile.timeout_ms", s.timeout_ms as f64, s.timeout_ms > 0, "> 0 ms")?;
    validate_sensors(&s.sensors, &s.fingers, usize::from(s.taxels_per_module))?;
    if let Some(big) = s.sensors.iter().find(|x| x.module > 255) {
        check("tactile.sensors.module", f64::from(big.module), false, "0..=255")?;
    }
    if let Some(t) = s.emulator.unplug_after_s {
        check("tactile.emulator.unplug_after_s", t, t.is_finite() && t >= 0.0, ">= 0 s")?;
    }
    Ok(())
}

/// The checks of a CAN tactile device that serde's types cannot make.
fn validate_can(c: &CanTactileConfig) -> Result<(), HwConfigError> {
    if c.map.is_empty() {
        c.legacy_layout().validate()?;
    }
    c.layout()?;
    if let Some(s) = &c.slcan {
        crate::slcan::bitrate_code(s.bitrate)
            .map_err(|e| HwConfigError::Can(format!("hw.tactile.slcan.bitrate: {e}")))?;
        if let Some(t) = s.unplug_after_s {
            check("tactile.slcan.unplug_after_s", t, t.is_finite() && t >= 0.0, ">= 0 s")?;
        }
    }
    check("tactile.rate_hz", c.rate_hz, c.rate_hz.is_finite() && c.rate_hz > 0.0, "> 0 Hz")?;
    check("tactile.timeout_ms", c.timeout_ms as f64, c.timeout_ms > 0, "> 0 ms")?;
    let per = f64::from(c.taxels_per_module);
    check("tactile.taxels_per_module", per, c.taxels_per_module > 0, ">= 1")?;
    // With an explicit map, modules and taxels_per_module are not used.
    let per_module = if c.map.is_empty() { usize::from(c.taxels_per_module) } else { usize::MAX };
    validate_sensors(&c.sensors, &c.fingers, per_module)?;
    let per = usize::from(c.taxels_per_module);
    for x in c.sensors.iter().filter(|_| c.map.is_empty()) {
        let end = x.module as usize * per + x.taxels();
        if end > usize::from(c.taxels) {
            let (name, module, taxels) = (x.name.clone(), x.module, c.taxels);
            return Err(HwConfigError::BeyondBoard { name, module, end, taxels });
        }
    }
    Ok(())
}

impl HwRigConfig {
    /// Checks what serde's types cannot.
    pub fn validate(&self) -> Result<(), HwConfigError> {
        match &self.tactile {
            TactileDevice::Sim => {}
            TactileDevice::XelaWs(x) => x.validate()?,
            TactileDevice::Serial(s) => validate_serial(s)?,
            TactileDevice::Can(c) => validate_can(c)?,
        }
        if let CameraDevice::V4l2(v) = &self.camera {
            check("camera.fps", v.fps, v.fps.is_finite() && v.fps > 0.0, "> 0 Hz")?;
            check("camera.width", f64::from(v.width), v.width > 0 && v.width <= 65535, "1..=65535 px")?;
            check("camera.height", f64::from(v.height), v.height > 0 && v.height <= 65535, "1..=65535 px")?;
            check("camera.buffers", f64::from(v.buffers), (2..=32).contains(&v.buffers), "2..=32")?;
            check("camera.timeout_ms", v.timeout_ms as f64, v.timeout_ms > 0, "> 0 ms")?;
            let startup = v.startup_timeout_ms;
            check("camera.startup_timeout_ms", startup as f64, startup > 0, "> 0 ms")?;
            let q = f64::from(v.jpeg_quality);
            check("camera.jpeg_quality", q, (1..=100).contains(&v.jpeg_quality), "1..=100")?;
            match (&v.calibration, &v.intrinsics) {
                (None, None) => {
                    return Err(HwConfigError::Camera(
                        "a V4L2 camera needs `calibration = \"camera.yaml\"` or inline `intrinsics` \
                         (width, height, fx, fy, cx, cy, distortion)"
                            .into(),
                    ));
                }
                (_, Some(k)) if (k.width, k.height) != (v.width, v.height) => {
                    return Err(HwConfigError::Camera(format!(
                        "intrinsics are for {}x{} px but the camera streams {}x{} px",
                        k.width, k.height, v.width, v.height
                    )));
                }
                _ => {}
            }
        }
        if let HandDevice::Robotiq(r) = &self.hand {
            r.validate()?;
        }
        if let HandDevice::Can(h) = &self.hand {
            h.ids().validate()?;
            check("hand.max_volts", h.max_volts, h.max_volts.is_finite() && h.max_volts > 0.0, "> 0 V")?;
            let hb = h.heartbeat_ms as f64;
            check("hand.heartbeat_ms", hb, (1..=1000).contains(&h.heartbeat_ms), "1..=1000 ms")?;
            if let TactileDevice::Can(c) = &self.tactile
                && let Some(collision) = c.collision_with_hand(&h.interface, &h.ids())
            {
                return Err(collision.into());
            }
        }
        Ok(())
    }

    /// Nominal tactile scan rate of the configured device (Hz), `sim_rate_hz`
    /// for the simulated and emulated sensors.
    pub fn tactile_rate_hz(&self, sim_rate_hz: f64) -> f64 {
        match &self.tactile {
            TactileDevice::Serial(s) if s.port != EMULATED_PORT => s.rate_hz,
            TactileDevice::Can(c) if c.slcan.as_ref().is_none_or(|s| s.port != EMULATED_PORT) => c.rate_hz,
            TactileDevice::XelaWs(x) if x.url != EMULATED_URL => x.rate_hz,
            _ => sim_rate_hz,
        }
    }
}

#[cfg(test)]
mod tests;
