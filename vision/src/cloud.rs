//! Depth and masks to what the estimators take: the partial point cloud of
//! the object `C(M_t, D_t)` (thesis (3.28)-(3.29)), depth in metres, pixel
//! masks and pinhole intrinsics.

use nalgebra::Point3;
use slidetrack_core::{CameraIntrinsics, DepthImage};
use slidetrack_estimators::roft::{DepthMap, Mask, Pinhole};

use crate::VisionError;

/// The pinhole part of `intrinsics` (RGB-D frames are rectified).
pub fn pinhole(intrinsics: &CameraIntrinsics) -> Pinhole {
    Pinhole {
        width: intrinsics.width,
        height: intrinsics.height,
        fx: intrinsics.fx,
        fy: intrinsics.fy,
        cx: intrinsics.cx,
        cy: intrinsics.cy,
    }
}

/// The depth in metres as `f32`, `0` where invalid.
pub fn depth_map(depth: &DepthImage) -> DepthMap {
    let scale = depth.scale_m as f32;
    DepthMap {
        width: depth.width,
        height: depth.height,
        depth_m: depth.data.iter().map(|d| f32::from(*d) * scale).collect(),
    }
}

/// A mask from a `width x height` buffer, non-zero inside; fails on a size mismatch.
pub fn mask(width: u32, height: u32, inside: &[u8]) -> Result<Mask, VisionError> {
    Mask::from_bytes(width, height, inside).ok_or(VisionError::BadImage {
        what: "mask",
        detail: format!("{} bytes for {width}x{height} px", inside.len()),
    })
}

/// The partial point cloud of a masked object.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MaskedCloud {
    /// Points with valid depth inside the mask, camera frame (m).
    pub points_in_camera: Vec<Point3<f64>>,
    /// Pixels in the mask, with or without depth (`L_t` of Sec. 4.1.6).
    pub mask_pixels: usize,
}

impl MaskedCloud {
    /// Fraction of mask pixels with valid depth (0 for an empty mask).
    pub fn valid_ratio(&self) -> f64 {
        if self.mask_pixels == 0 { 0.0 } else { self.points_in_camera.len() as f64 / self.mask_pixels as f64 }
    }
}

/// `C(M, D)` (3.29): every pixel of `mask` with a valid depth, back-projected
/// with `p_uv(d)` (3.28). Fails when the mask and depth sizes differ.
pub fn masked_cloud(depth: &DepthImage, mask: &Mask, camera: &Pinhole) -> Result<MaskedCloud, VisionError> {
    VisionError::check_size("mask", (mask.width(), mask.height()), (depth.width, depth.height))?;
    let mut cloud = MaskedCloud::default();
    for (u, v) in mask.pixels() {
        cloud.mask_pixels += 1;
        if let Some(d) = depth.depth_m(u, v) {
            let [x, y, z] = camera.back_project(f64::from(u), f64::from(v), d);
            cloud.points_in_camera.push(Point3::new(x, y, z));
        }
    }
    Ok(cloud)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_cloud_back_projects_valid_pixels_only() {
        let camera = Pinhole { width: 4, height: 3, fx: 2.0, fy: 2.0, cx: 1.5, cy: 1.0 };
        let depth = DepthImage {
            width: 4,
            height: 3,
            data: vec![0, 1000, 0, 0, 0, 2000, 500, 0, 0, 0, 0, 0],
            scale_m: 0.001,
        };
        let m = mask(4, 3, &[0, 1, 1, 0, 0, 1, 1, 0, 0, 0, 0, 0]).unwrap();
        let cloud = masked_cloud(&depth, &m, &camera).unwrap();
        assert_eq!(cloud.mask_pixels, 4);
        assert_eq!(cloud.points_in_camera.len(), 3);
        // Pixel (1, 0) at 1 m: x = (1 - 1.5) / 2, y = (0 - 1) / 2.
        assert_eq!(cloud.points_in_camera[0], Point3::new(-0.25, -0.5, 1.0));
        assert!((cloud.valid_ratio() - 0.75).abs() < 1e-12);
        assert!(mask(4, 3, &[0; 5]).is_err());
        let wrong = Mask::empty(2, 2);
        assert!(matches!(masked_cloud(&depth, &wrong, &camera), Err(VisionError::SizeMismatch { .. })));
        let map = depth_map(&depth);
        assert_eq!(map.at(1, 0), Some(1.0f32 as f64));
        assert_eq!(map.at(0, 0), None);
    }
}
