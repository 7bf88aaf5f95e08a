//! [`MaskRenderer`]: the object's mask, rendered from its mesh at a pose.

use nalgebra::Isometry3;
use slidetrack_core::{CameraIntrinsics, DepthImage};
use slidetrack_estimators::roft::Mask;
use slidetrack_render::{PixelRegion, Rasterizer, TriangleMesh};

/// Renders the object's mesh with the colour intrinsics (the project's
/// z-buffer [`Rasterizer`], the one that renders the simulated camera and
/// ROFT's depth check) and keeps the pixels it covers, optionally only
/// those whose measured depth agrees with the rendered one.
pub struct MaskRenderer {
    rasterizer: Rasterizer,
    mesh: TriangleMesh,
    depth_tolerance_m: Option<f64>,
    depth_m: Vec<f32>,
    triangle: Vec<u32>,
}

impl MaskRenderer {
    /// A renderer of `mesh` (object frame, m) through `intrinsics` (pinhole
    /// part; the images are registered and rectified). With
    /// `depth_tolerance_m`, pixels whose measured depth is valid and differs
    /// from the rendered depth by more than it (m) are left out: whatever
    /// occludes the object (a hand) is not in the mask.
    pub fn new(
        mesh: TriangleMesh,
        intrinsics: &CameraIntrinsics,
        depth_tolerance_m: Option<f64>,
    ) -> MaskRenderer {
        MaskRenderer {
            rasterizer: Rasterizer::new(intrinsics),
            mesh,
            depth_tolerance_m,
            depth_m: Vec::new(),
            triangle: Vec::new(),
        }
    }

    /// The mask of the object at `camera_from_object`; `depth` is the
    /// frame's registered depth (used only with a depth tolerance).
    pub fn render(&mut self, camera_from_object: &Isometry3<f64>, depth: Option<&DepthImage>) -> Mask {
        let (width, height) = self.rasterizer.size();
        let region = PixelRegion::full(width, height);
        self.rasterizer.render(&self.mesh, camera_from_object, region, &mut self.depth_m, &mut self.triangle);
        let measured = depth.filter(|d| (d.width, d.height) == (width, height));
        let mut mask = Mask::empty(width, height);
        for (i, rendered_m) in self.depth_m.iter().enumerate() {
            if !rendered_m.is_finite() {
                continue;
            }
            if let (Some(tolerance_m), Some(d)) = (self.depth_tolerance_m, measured) {
                let raw = d.data[i];
                if raw != 0 && (f64::from(raw) * d.scale_m - f64::from(*rendered_m)).abs() > tolerance_m {
                    continue;
                }
            }
            mask.insert(i as u32 % width, i as u32 / width);
        }
        mask
    }
}

#[cfg(test)]
mod tests {
    use nalgebra::{Translation3, UnitQuaternion};

    use super::*;

    fn camera() -> CameraIntrinsics {
        CameraIntrinsics {
            width: 64,
            height: 48,
            fx: 60.0,
            fy: 60.0,
            cx: 31.5,
            cy: 23.5,
            distortion: [0.0; 5],
        }
    }

    fn count(mask: &Mask) -> usize {
        (0..mask.height())
            .flat_map(|v| (0..mask.width()).map(move |u| (u, v)))
            .filter(|&(u, v)| mask.contains(u, v))
            .count()
    }

    #[test]
    fn an_occluder_in_front_is_cut_out_of_the_mask() {
        let pose = Isometry3::from_parts(Translation3::new(0.0, 0.0, 0.5), UnitQuaternion::identity());
        let mut renderer = MaskRenderer::new(TriangleMesh::cuboid([0.2, 0.2, 0.1]), &camera(), Some(0.02));
        // The box's front face at 0.45 m: ±0.1 m is ±13.3 px around the centre.
        let mut depth = DepthImage { width: 64, height: 48, data: vec![450; 64 * 48], scale_m: 0.001 };
        let full = count(&renderer.render(&pose, Some(&depth)));
        assert!((26 * 26..=28 * 28).contains(&full), "{full}");
        // A hand at 0.3 m over the left half of the image.
        for v in 0..48 {
            for u in 0..32 {
                depth.data[v * 64 + u] = 300;
            }
        }
        let mask = renderer.render(&pose, Some(&depth));
        assert!(!mask.contains(25, 23) && mask.contains(38, 23));
        assert!(count(&mask) < full * 6 / 10);
        // Missing depth keeps the pixel; no tolerance keeps everything.
        depth.data.fill(0);
        assert_eq!(count(&renderer.render(&pose, Some(&depth))), full);
    }
}
