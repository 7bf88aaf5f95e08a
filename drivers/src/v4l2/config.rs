//! The `[hw.camera]` table of `kind = "v4l2"`: the device, its format and
//! rate, and its calibration.

use std::path::PathBuf;

use serde::{Deserialize, Serialize};
use slidetrack_core::{CameraIntrinsics, CameraPlacement};

use crate::config::error::{HwConfigError, check};

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

impl V4l2CameraConfig {
    /// The checks that serde's types cannot make.
    pub fn validate(&self) -> Result<(), HwConfigError> {
        let v = self;
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
            (None, None) => Err(HwConfigError::Camera(
                "a V4L2 camera needs `calibration = \"camera.yaml\"` or inline `intrinsics` \
                 (width, height, fx, fy, cx, cy, distortion)"
                    .into(),
            )),
            (_, Some(k)) if (k.width, k.height) != (v.width, v.height) => {
                Err(HwConfigError::Camera(format!(
                    "intrinsics are for {}x{} px but the camera streams {}x{} px",
                    k.width, k.height, v.width, v.height
                )))
            }
            _ => Ok(()),
        }
    }
}
