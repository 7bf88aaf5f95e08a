//! The intrinsics of a V4L2 camera of the rig TOML (`[hw.camera]`, the
//! nodes of `[rgbd]`): its calibration file or its inline table.

use std::path::Path;

use anyhow::{Context, Result, bail};
use slidetrack_calibration::camera_info::read_camera_info;
use slidetrack_core::{CameraIntrinsics, parse_toml};
use slidetrack_drivers::config::V4l2CameraConfig;

/// The intrinsics of a V4L2 camera: its calibration file (ROS `camera_info`
/// or OpenCV YAML, or TOML with the fields of `intrinsics`) or the inline table.
pub fn v4l2_intrinsics(v: &V4l2CameraConfig) -> Result<CameraIntrinsics> {
    let intrinsics = match (&v.calibration, &v.intrinsics) {
        (Some(path), _) => read_intrinsics(path, v.width, v.height)?,
        (None, Some(k)) => k.clone(),
        (None, None) => bail!("hw.camera needs `calibration` or inline `intrinsics`"),
    };
    if (intrinsics.width, intrinsics.height) != (v.width, v.height) {
        bail!(
            "the camera intrinsics are for {}x{} px but hw.camera streams {}x{} px",
            intrinsics.width,
            intrinsics.height,
            v.width,
            v.height
        );
    }
    Ok(intrinsics)
}

fn read_intrinsics(path: &Path, width: u32, height: u32) -> Result<CameraIntrinsics> {
    if path.extension().is_some_and(|e| e == "toml") {
        let text = std::fs::read_to_string(path)
            .with_context(|| format!("cannot read camera calibration {}", path.display()))?;
        return Ok(parse_toml(&text, &path.display().to_string())?);
    }
    let info = read_camera_info(path)?;
    let sized = info.has_image_size();
    let mut intrinsics = info.intrinsics;
    if !sized {
        // OpenCV files may omit the size: it is the size the camera streams.
        (intrinsics.width, intrinsics.height) = (width, height);
    }
    Ok(intrinsics)
}
