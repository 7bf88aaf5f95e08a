//! Configuration of the simulated camera: intrinsics, placement, image
//! pipeline, background.

use nalgebra::{Isometry3, Vector3};
use serde::{Deserialize, Serialize};
use slidetrack_core::{CameraIntrinsics, CameraPlacement, PixelFormat};

use super::error::SimCameraError;

/// Configuration of the simulated camera (the `[camera]` table of the rig TOML).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SimCameraConfig {
    /// Intrinsics used for rendering; they are also the simulator's "true"
    /// calibration.
    pub intrinsics: CameraIntrinsics,
    /// Where the camera sits in the hand frame.
    pub placement: CameraPlacement,
    /// Frame rate (Hz).
    pub fps: f64,
    /// Pixel layout of the rendered frames. Default `Gray8`: on one core the
    /// whole frame path (render, JPEG, tracked detection, pose) takes about
    /// 2.5 ms in gray and 3.5 ms in RGB (JPEG alone 1.6 vs 2.1 ms), and the
    /// budget is 3 ms (see the `camera_frame` benchmark of the calibration crate).
    pub pixel_format: PixelFormat,
    /// Standard deviation of the additive Gaussian sensor noise (gray levels, 0..255 scale).
    pub noise_std_gray: f64,
    /// Standard deviation of the Gaussian optical blur (px); 0 disables it.
    pub blur_sigma_px: f64,
    /// JPEG quality of the encoded frames, 1..=100.
    pub jpeg_quality: u8,
    /// The static textured plane behind the object.
    pub background: BackgroundConfig,
}

impl Default for SimCameraConfig {
    fn default() -> Self {
        SimCameraConfig {
            intrinsics: CameraIntrinsics {
                width: 640,
                height: 480,
                fx: 600.0,
                fy: 600.0,
                cx: 321.5,
                cy: 238.0,
                distortion: [-0.1, 0.02, 0.0004, -0.0003, 0.0],
            },
            placement: CameraPlacement::default(),
            fps: 30.0,
            pixel_format: PixelFormat::Gray8,
            noise_std_gray: 2.0,
            blur_sigma_px: 0.7,
            jpeg_quality: 85,
            background: BackgroundConfig::default(),
        }
    }
}

impl SimCameraConfig {
    /// The camera pose in the hand frame.
    pub fn hand_from_camera(&self) -> Result<Isometry3<f64>, SimCameraError> {
        Ok(self.placement.hand_from_camera()?)
    }

    /// Time between frames (ns), rounded.
    pub fn frame_period_ns(&self) -> u64 {
        (1e9 / self.fps).round() as u64
    }

    /// Checks every number of the configuration.
    pub fn validate(&self) -> Result<(), SimCameraError> {
        let c = &self.intrinsics;
        if c.width == 0 || c.height == 0 || c.width > 65535 || c.height > 65535 {
            return Err(SimCameraError::BadImageSize { width: c.width, height: c.height });
        }
        if !(c.fx.is_finite() && c.fy.is_finite() && c.fx > 0.0 && c.fy > 0.0) {
            return Err(SimCameraError::BadFocalLength { fx: c.fx, fy: c.fy });
        }
        check_range("intrinsics.cx", c.cx, c.cx.is_finite(), "finite")?;
        check_range("intrinsics.cy", c.cy, c.cy.is_finite(), "finite")?;
        for (&k, what) in c.distortion.iter().zip(["k1", "k2", "p1", "p2", "k3"]) {
            check_range(what, k, k.is_finite() && k.abs() < 1.0, "|value| < 1")?;
        }
        check_range("fps", self.fps, self.fps.is_finite() && self.fps > 0.0, "> 0 Hz")?;
        let noise = self.noise_std_gray;
        check_range("noise_std_gray", noise, (0.0..=64.0).contains(&noise), "0..=64 gray levels")?;
        let blur = self.blur_sigma_px;
        check_range("blur_sigma_px", blur, (0.0..=10.0).contains(&blur), "0..=10 px")?;
        let q = self.jpeg_quality;
        check_range("jpeg_quality", q.into(), (1..=100).contains(&q), "1..=100")?;
        self.background.validate()?;
        self.hand_from_camera().map(|_| ())
    }
}

pub(super) fn check_range(
    what: &'static str,
    value: f64,
    ok: bool,
    expected: &'static str,
) -> Result<(), SimCameraError> {
    if ok { Ok(()) } else { Err(SimCameraError::OutOfRange { what, value, expected }) }
}

/// The static textured plane behind the object.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct BackgroundConfig {
    /// A point of the plane in the hand frame (m).
    pub point_in_hand_m: [f64; 3],
    /// The plane normal in the hand frame (any length, pointing towards the camera).
    pub normal_in_hand: [f64; 3],
    /// Seed of the procedural texture (independent of the noise seed, so the
    /// scene stays the same across trials).
    pub texture_seed: u64,
    /// Size of the smallest texture features (m).
    pub feature_size_m: f64,
    /// Mean colour of the plane, sRGB 0..255.
    pub mean_rgb: [u8; 3],
    /// Strength of the smooth texture, 0 (flat) ..= 1.
    pub contrast: f64,
    /// Number of random rectangles and bars (clutter with sharp edges).
    pub clutter_count: usize,
}

impl Default for BackgroundConfig {
    fn default() -> Self {
        BackgroundConfig {
            point_in_hand_m: [-0.10, 0.0, 0.0],
            normal_in_hand: [1.0, 0.0, 0.0],
            texture_seed: 0x51_1D_E7_AC,
            feature_size_m: 0.01,
            mean_rgb: [118, 122, 112],
            contrast: 0.5,
            clutter_count: 80,
        }
    }
}

impl BackgroundConfig {
    fn validate(&self) -> Result<(), SimCameraError> {
        let n = Vector3::from(self.normal_in_hand);
        if !(n.norm().is_finite() && n.norm() > 1e-9) {
            return Err(SimCameraError::BadBackgroundNormal { normal_in_hand: self.normal_in_hand });
        }
        let f = self.feature_size_m;
        check_range("background.feature_size_m", f, f.is_finite() && f > 1e-4, "> 0.1 mm")?;
        let c = self.contrast;
        check_range("background.contrast", c, (0.0..=1.0).contains(&c), "0..=1")
    }
}
