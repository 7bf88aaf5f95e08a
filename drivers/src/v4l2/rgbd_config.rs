//! The `[rgbd]` table of a rig TOML: the RGB-D camera the vision trackers
//! run on live (`slidetrack vision track --live --rig rig.toml`).
//!
//! ```toml
//! [rgbd]
//! kind = "v4l2"                  # or "recording": a recorded stand-in
//! depth_scale_m = 0.001          # metres per Z16 unit (RealSense: 0.001)
//! pairing_tolerance_ms = 16.0    # default: half the colour frame period
//! [rgbd.color]                   # a V4L2 node, as `[hw.camera]`
//! device = "/dev/video4"
//! pixel_format = "YUYV"          # YUYV, MJPG or GREY
//! intrinsics = { width = 640, height = 480, fx = 615.0, fy = 615.0, cx = 320.0, cy = 240.0, distortion = [0.0, 0.0, 0.0, 0.0, 0.0] }
//! [rgbd.depth]
//! device = "/dev/video0"
//! pixel_format = "Z16"
//! intrinsics = { width = 640, height = 480, fx = 385.0, fy = 385.0, cx = 320.0, cy = 240.0, distortion = [0.0, 0.0, 0.0, 0.0, 0.0] }
//! [rgbd.depth_to_color]          # absent: depth already registered to colour
//! rotation_row_major = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]
//! translation_m = [0.015, 0.0, 0.0]
//! ```

use std::path::PathBuf;

use serde::{Deserialize, Serialize};
use slidetrack_core::CameraIntrinsics;
use thiserror::Error;

use crate::v4l2::config::{V4l2CameraConfig, V4l2PixelFormat};

/// The RGB-D camera of a rig.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "lowercase")]
pub enum RgbdCameraConfig {
    /// Colour and depth from two V4L2 nodes of one camera (a RealSense over
    /// `uvcvideo`).
    V4l2(Box<V4l2RgbdConfig>),
    /// A recording replayed as two cameras, standing in for the device
    /// (dry runs, tests).
    Recording(Box<RecordedRgbdConfig>),
}

/// How fast a recording standing in for a camera delivers its frames.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ReplayPace {
    /// On the wall clock, as the camera did: a reader slower than the
    /// frame rate loses frames, as it would on the device.
    #[default]
    Realtime,
    /// Every frame, each once the reader has finished with the previous
    /// one, on the recording's own clock: a slow machine processes the same
    /// frames with the same times as a fast one (reproducible dry runs).
    EveryFrame,
}

/// Colour and depth from two V4L2 nodes.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct V4l2RgbdConfig {
    /// The colour node (YUYV, MJPG or GREY) and its intrinsics.
    pub color: V4l2CameraConfig,
    /// The depth node and its intrinsics; its table must say
    /// `pixel_format = "Z16"` (a node's table starts from `[hw.camera]`'s
    /// defaults, MJPG).
    pub depth: V4l2CameraConfig,
    /// Metres per depth unit.
    pub depth_scale_m: f64,
    /// Where the depth camera is seen from the colour camera; absent when
    /// the depth stream is already registered to the colour camera.
    pub depth_to_color: Option<DepthToColor>,
    /// Largest time between a paired colour and depth frame (ms); default
    /// half the colour frame period.
    pub pairing_tolerance_ms: Option<f64>,
    /// Longest time without a complete pair before the camera counts as
    /// stalled (ms).
    pub pair_timeout_ms: u64,
}

impl Default for V4l2RgbdConfig {
    fn default() -> Self {
        V4l2RgbdConfig {
            color: V4l2CameraConfig { device: "/dev/video4".into(), ..V4l2CameraConfig::default() },
            depth: V4l2CameraConfig {
                device: "/dev/video0".into(),
                pixel_format: V4l2PixelFormat::Z16,
                ..V4l2CameraConfig::default()
            },
            depth_scale_m: 0.001,
            depth_to_color: None,
            pairing_tolerance_ms: None,
            pair_timeout_ms: 5000,
        }
    }
}

/// A recording replayed as the camera: an RGB-D session (`/rgbd/color`,
/// `/rgbd/depth`, `/rgbd/calibration`) or a directory of
/// `NNNNNN-color.png` and `NNNNNN-depth.png` files.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RecordedRgbdConfig {
    /// A session file (relative paths from the rig TOML's directory).
    pub session: Option<PathBuf>,
    /// A directory of colour and depth PNG files.
    pub directory: Option<PathBuf>,
    /// Frame rate of a directory's frames (Hz).
    pub fps: f64,
    /// Metres per depth unit of a directory's depth PNGs (a session's depth
    /// carries its own).
    pub depth_scale_m: f64,
    /// Colour intrinsics; default: a session's `/rgbd/calibration`
    /// (required for a directory).
    pub color_intrinsics: Option<CameraIntrinsics>,
    /// Depth intrinsics; default: the colour intrinsics.
    pub depth_intrinsics: Option<CameraIntrinsics>,
    /// Where the depth camera is seen from the colour camera; absent when
    /// the recorded depth is registered to the colour camera already.
    pub depth_to_color: Option<DepthToColor>,
    /// Colour frames stamped this much later than their depth frames (ms),
    /// to replay unsynchronised nodes.
    pub color_delay_ms: f64,
    /// Largest time between a paired colour and depth frame (ms); default
    /// half the frame period.
    pub pairing_tolerance_ms: Option<f64>,
    /// Longest time without a complete pair (ms).
    pub pair_timeout_ms: u64,
    /// `"realtime"` (default) or `"every-frame"`.
    pub pace: ReplayPace,
}

impl Default for RecordedRgbdConfig {
    fn default() -> Self {
        RecordedRgbdConfig {
            session: None,
            directory: None,
            fps: 30.0,
            depth_scale_m: 0.001,
            color_intrinsics: None,
            depth_intrinsics: None,
            depth_to_color: None,
            color_delay_ms: 0.0,
            pairing_tolerance_ms: None,
            pair_timeout_ms: 5000,
            pace: ReplayPace::Realtime,
        }
    }
}

/// The depth-to-colour extrinsics: `p_color = R p_depth + t`, in metres,
/// inline or from a TOML file with the same fields. librealsense prints the
/// factory values (`rs-enumerate-devices -c`) with the rotation in column-major
/// order (`rs2_extrinsics`), hence the two spellings of the rotation.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct DepthToColor {
    /// `R` row by row.
    pub rotation_row_major: Option<[f64; 9]>,
    /// `R` column by column (as librealsense's `rs2_extrinsics.rotation`).
    pub rotation_column_major: Option<[f64; 9]>,
    /// `t` (m).
    pub translation_m: Option<[f64; 3]>,
    /// A TOML file with `rotation_row_major` or `rotation_column_major`, and
    /// `translation_m` (relative paths from the rig TOML's directory).
    pub file: Option<PathBuf>,
}

/// The extrinsics as numbers: `R` row-major and `t` (m).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Extrinsics {
    /// `R`, row-major.
    pub rotation_row_major: [f64; 9],
    /// `t` (m).
    pub translation_m: [f64; 3],
}

impl DepthToColor {
    /// The inline values (not the file's), checked; `field` names the table
    /// in messages (`rgbd.depth_to_color`).
    pub fn inline(&self, field: &str) -> Result<Extrinsics, RgbdConfigError> {
        let bad = |detail: String| RgbdConfigError::Extrinsics { field: field.into(), detail };
        let rotation = match (self.rotation_row_major, self.rotation_column_major) {
            (Some(r), None) => r,
            (None, Some(c)) => [c[0], c[3], c[6], c[1], c[4], c[7], c[2], c[5], c[8]],
            (Some(_), Some(_)) => {
                return Err(bad("give rotation_row_major or rotation_column_major, not both".into()));
            }
            (None, None) => return Err(bad("needs rotation_row_major or rotation_column_major".into())),
        };
        let translation = self.translation_m.ok_or_else(|| bad("needs translation_m (m)".into()))?;
        if let Some(e) = rotation_error(&rotation) {
            return Err(bad(format!("the rotation is not a rotation matrix ({e})")));
        }
        if translation.iter().any(|x| !x.is_finite() || x.abs() > 1.0) {
            return Err(bad(format!("translation_m {translation:?} is not within 1 m (metres, not mm?)")));
        }
        Ok(Extrinsics { rotation_row_major: rotation, translation_m: translation })
    }
}

/// What is wrong with a row-major 3x3 matrix as a rotation: rows not unit
/// length or orthogonal within 1e-3, or a determinant that is not +1.
fn rotation_error(r: &[f64; 9]) -> Option<String> {
    if r.iter().any(|x| !x.is_finite()) {
        return Some("not finite".into());
    }
    let row = |i: usize| [r[3 * i], r[3 * i + 1], r[3 * i + 2]];
    let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    for i in 0..3 {
        for j in i..3 {
            let want = if i == j { 1.0 } else { 0.0 };
            let got = dot(row(i), row(j));
            if (got - want).abs() > 1e-3 {
                return Some(format!("rows {i} and {j} have dot product {got:.4}, not {want}"));
            }
        }
    }
    let det = r[0] * (r[4] * r[8] - r[5] * r[7]) - r[1] * (r[3] * r[8] - r[5] * r[6])
        + r[2] * (r[3] * r[7] - r[4] * r[6]);
    (det < 0.0).then(|| format!("determinant {det:.3}: a reflection"))
}

/// An `[rgbd]` table that cannot work; every variant names the field.
#[derive(Clone, Debug, Error, PartialEq)]
pub enum RgbdConfigError {
    /// A number outside its range.
    #[error("{field} = {value} is out of range ({expected})")]
    OutOfRange {
        /// The setting, as in the file (`rgbd.depth_scale_m`).
        field: String,
        /// Its value.
        value: f64,
        /// The valid range, in words.
        expected: &'static str,
    },
    /// A node streaming the wrong kind of image.
    #[error("{field} = {format:?}: {expected}")]
    PixelFormat {
        /// The setting.
        field: String,
        /// What it says.
        format: V4l2PixelFormat,
        /// What it must be.
        expected: &'static str,
    },
    /// Missing or inconsistent intrinsics.
    #[error("{field}: {detail}")]
    Intrinsics {
        /// The setting.
        field: String,
        /// What is wrong.
        detail: String,
    },
    /// Bad extrinsics.
    #[error("{field}: {detail}")]
    Extrinsics {
        /// The setting.
        field: String,
        /// What is wrong.
        detail: String,
    },
    /// A recording that names no recording, or two.
    #[error("rgbd: a `kind = \"recording\"` camera needs exactly one of `session` and `directory`")]
    Recording,
}

fn range(field: &str, value: f64, ok: bool, expected: &'static str) -> Result<(), RgbdConfigError> {
    if ok { Ok(()) } else { Err(RgbdConfigError::OutOfRange { field: field.into(), value, expected }) }
}

fn check_common(
    depth_scale_m: f64,
    tolerance_ms: Option<f64>,
    pair_timeout_ms: u64,
    depth_to_color: Option<&DepthToColor>,
) -> Result<(), RgbdConfigError> {
    let s = depth_scale_m;
    range("rgbd.depth_scale_m", s, s.is_finite() && s > 0.0 && s <= 1.0, "(0, 1] m per unit")?;
    if let Some(t) = tolerance_ms {
        range("rgbd.pairing_tolerance_ms", t, t.is_finite() && t >= 0.0, ">= 0 ms")?;
    }
    range("rgbd.pair_timeout_ms", pair_timeout_ms as f64, pair_timeout_ms > 0, "> 0 ms")?;
    if let Some(d) = depth_to_color.filter(|d| d.file.is_none()) {
        d.inline("rgbd.depth_to_color")?;
    }
    Ok(())
}

fn check_node(field: &str, v: &V4l2CameraConfig) -> Result<(), RgbdConfigError> {
    let fps = v.fps;
    range(&format!("{field}.fps"), fps, fps.is_finite() && fps > 0.0, "> 0 Hz")?;
    let (w, h) = (f64::from(v.width), f64::from(v.height));
    range(&format!("{field}.width"), w, (1..=65535).contains(&v.width), "1..=65535 px")?;
    range(&format!("{field}.height"), h, (1..=65535).contains(&v.height), "1..=65535 px")?;
    let b = f64::from(v.buffers);
    range(&format!("{field}.buffers"), b, (2..=32).contains(&v.buffers), "2..=32")?;
    range(&format!("{field}.timeout_ms"), v.timeout_ms as f64, v.timeout_ms > 0, "> 0 ms")?;
    let s = v.startup_timeout_ms;
    range(&format!("{field}.startup_timeout_ms"), s as f64, s > 0, "> 0 ms")?;
    let q = f64::from(v.jpeg_quality);
    range(&format!("{field}.jpeg_quality"), q, (1..=100).contains(&v.jpeg_quality), "1..=100")?;
    let detail = match (&v.calibration, &v.intrinsics) {
        (None, None) => "needs `calibration = \"camera.yaml\"` or inline `intrinsics`".to_string(),
        (_, Some(k)) if (k.width, k.height) != (v.width, v.height) => format!(
            "intrinsics are for {}x{} px but the node streams {}x{} px",
            k.width, k.height, v.width, v.height
        ),
        _ => return Ok(()),
    };
    Err(RgbdConfigError::Intrinsics { field: field.into(), detail })
}

impl RgbdCameraConfig {
    /// Checks what serde's types cannot.
    pub fn validate(&self) -> Result<(), RgbdConfigError> {
        match self {
            RgbdCameraConfig::V4l2(c) => {
                check_common(
                    c.depth_scale_m,
                    c.pairing_tolerance_ms,
                    c.pair_timeout_ms,
                    c.depth_to_color.as_ref(),
                )?;
                check_node("rgbd.color", &c.color)?;
                check_node("rgbd.depth", &c.depth)?;
                if c.color.pixel_format == V4l2PixelFormat::Z16 {
                    let (field, format) = ("rgbd.color.pixel_format".into(), c.color.pixel_format);
                    return Err(RgbdConfigError::PixelFormat {
                        field,
                        format,
                        expected: "YUYV, MJPG or GREY",
                    });
                }
                if c.depth.pixel_format != V4l2PixelFormat::Z16 {
                    let (field, format) = ("rgbd.depth.pixel_format".into(), c.depth.pixel_format);
                    return Err(RgbdConfigError::PixelFormat { field, format, expected: "Z16" });
                }
                if c.depth_to_color.is_none()
                    && (c.color.width, c.color.height) != (c.depth.width, c.depth.height)
                {
                    return Err(RgbdConfigError::Extrinsics {
                        field: "rgbd.depth_to_color".into(),
                        detail:
                            "colour and depth differ in size, so depth is not registered: give the extrinsics"
                                .into(),
                    });
                }
            }
            RgbdCameraConfig::Recording(r) => {
                check_common(
                    r.depth_scale_m,
                    r.pairing_tolerance_ms,
                    r.pair_timeout_ms,
                    r.depth_to_color.as_ref(),
                )?;
                if r.session.is_some() == r.directory.is_some() {
                    return Err(RgbdConfigError::Recording);
                }
                range("rgbd.fps", r.fps, r.fps.is_finite() && r.fps > 0.0, "> 0 Hz")?;
                let d = r.color_delay_ms;
                range("rgbd.color_delay_ms", d, d.is_finite() && d.abs() < 1000.0, "within 1000 ms")?;
                if r.directory.is_some() && r.color_intrinsics.is_none() {
                    let detail = "a directory of frames needs `color_intrinsics`".into();
                    return Err(RgbdConfigError::Intrinsics {
                        field: "rgbd.color_intrinsics".into(),
                        detail,
                    });
                }
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests;
