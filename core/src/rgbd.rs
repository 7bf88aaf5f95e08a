//! RGB-D frames (colour and registered depth) and the true pose and velocity
//! of the object at a frame (from a simulator or an annotated dataset).

use nalgebra::{Isometry3, Vector3};

use crate::{CameraIntrinsics, Image, TimeNs};

/// A depth image as RGB-D cameras deliver it (V4L2 `Z16`, ROS `16UC1`):
/// one `u16` per pixel, `scale_m` metres per unit, `0` for no measurement.
#[derive(Clone, Debug, PartialEq)]
pub struct DepthImage {
    /// Width (px).
    pub width: u32,
    /// Height (px).
    pub height: u32,
    /// `width * height` values, row-major.
    pub data: Vec<u16>,
    /// Metres per unit: `0.001` for millimetres (RealSense, `16UC1`),
    /// `0.0001` for YCB-Video's PNGs.
    pub scale_m: f64,
}

impl DepthImage {
    /// An image of invalid pixels.
    pub fn invalid(width: u32, height: u32, scale_m: f64) -> DepthImage {
        DepthImage { width, height, data: vec![0; width as usize * height as usize], scale_m }
    }

    /// The depth at `(u, v)` in metres, `None` when invalid or outside.
    pub fn depth_m(&self, u: u32, v: u32) -> Option<f64> {
        if u >= self.width || v >= self.height {
            return None;
        }
        let raw = self.data[v as usize * self.width as usize + u as usize];
        (raw != 0).then(|| f64::from(raw) * self.scale_m)
    }

    /// The same depths in millimetres (`16UC1`), rounded; depths beyond
    /// 65.535 m become invalid.
    pub fn to_millimetres(&self) -> DepthImage {
        let factor = self.scale_m / 0.001;
        let data = self
            .data
            .iter()
            .map(|&d| {
                let mm = (f64::from(d) * factor).round();
                if mm > 0.0 && mm <= f64::from(u16::MAX) { mm as u16 } else { 0 }
            })
            .collect();
        DepthImage { width: self.width, height: self.height, data, scale_m: 0.001 }
    }

    /// Fraction of pixels with a depth.
    pub fn valid_fraction(&self) -> f64 {
        if self.data.is_empty() {
            return 0.0;
        }
        self.data.iter().filter(|d| **d != 0).count() as f64 / self.data.len() as f64
    }
}

/// One RGB-D frame: colour and depth registered to the same pinhole camera.
#[derive(Clone, Debug)]
pub struct RgbdFrame {
    /// Acquisition time on the session clock.
    pub t: TimeNs,
    /// The camera's frame counter.
    pub sequence: u64,
    /// Colour, [`crate::PixelFormat::Rgb8`].
    pub color: Image,
    /// Depth, registered to the colour image.
    pub depth: DepthImage,
    /// Intrinsics of both images (no distortion: registered, rectified).
    pub intrinsics: CameraIntrinsics,
}

/// The simulator's truth about the object at one frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ObjectTruth {
    /// Time of the frame.
    pub t: TimeNs,
    /// `camera_from_object` (m).
    pub camera_from_object: Isometry3<f64>,
    /// Velocity of the object frame's origin `ṗ` in the camera frame (m/s).
    pub linear_velocity_mps: Vector3<f64>,
    /// Angular velocity `ω` in the camera frame (rad/s).
    pub angular_velocity_radps: Vector3<f64>,
}
