//! [`Rasterizer`]: a z-buffer rasterizer of triangle meshes through a pinhole
//! camera (no distortion). Pixel `(u, v)` is sampled at its centre, the point
//! `(u, v)` of the image plane, as the back-projection `p_uv(d)` of the
//! thesis (3.28) assumes. Depth is interpolated perspective-correctly.

use nalgebra::{Isometry3, Point3};
use slidetrack_core::CameraIntrinsics;

use crate::mesh::TriangleMesh;

/// Triangles closer than this to the camera plane (m) are not drawn.
const NEAR_M: f64 = 1e-3;

/// A rectangle of pixels, `[u0, u1) x [v0, v1)`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PixelRegion {
    /// First column.
    pub u0: u32,
    /// First row.
    pub v0: u32,
    /// One past the last column.
    pub u1: u32,
    /// One past the last row.
    pub v1: u32,
}

impl PixelRegion {
    /// The whole `width x height` image.
    pub fn full(width: u32, height: u32) -> PixelRegion {
        PixelRegion { u0: 0, v0: 0, u1: width, v1: height }
    }

    /// Width (px).
    pub fn width(&self) -> u32 {
        self.u1.saturating_sub(self.u0)
    }

    /// Height (px).
    pub fn height(&self) -> u32 {
        self.v1.saturating_sub(self.v0)
    }

    /// Number of pixels.
    pub fn len(&self) -> usize {
        self.width() as usize * self.height() as usize
    }

    /// No pixels.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The smallest region holding `pixels`, `None` for none.
    pub fn around(pixels: &[(u32, u32)]) -> Option<PixelRegion> {
        let (&(u, v), rest) = pixels.split_first()?;
        let mut r = PixelRegion { u0: u, v0: v, u1: u + 1, v1: v + 1 };
        for &(u, v) in rest {
            r.u0 = r.u0.min(u);
            r.v0 = r.v0.min(v);
            r.u1 = r.u1.max(u + 1);
            r.v1 = r.v1.max(v + 1);
        }
        Some(r)
    }
}

/// The rasterizer of one camera.
#[derive(Clone, Debug, PartialEq)]
pub struct Rasterizer {
    width: u32,
    height: u32,
    fx: f64,
    fy: f64,
    cx: f64,
    cy: f64,
    cull_back_faces: bool,
}

impl Rasterizer {
    /// A rasterizer with the pinhole part of `intrinsics` (distortion is
    /// ignored: RGB-D images are registered and rectified). Back faces are
    /// culled only for meshes known to have outward normals
    /// ([`Rasterizer::culling_back_faces`]).
    pub fn new(intrinsics: &CameraIntrinsics) -> Rasterizer {
        Rasterizer {
            width: intrinsics.width,
            height: intrinsics.height,
            fx: intrinsics.fx,
            fy: intrinsics.fy,
            cx: intrinsics.cx,
            cy: intrinsics.cy,
            cull_back_faces: false,
        }
    }

    /// The same rasterizer skipping triangles that face away from the camera
    /// (for closed meshes with outward, counter-clockwise triangles).
    pub fn culling_back_faces(mut self) -> Rasterizer {
        self.cull_back_faces = true;
        self
    }

    /// Image size (px).
    pub fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    /// Renders `mesh` at `camera_from_object` over `region`: `depth_m[i]` is
    /// the depth (m) of the nearest surface through the `i`-th pixel of the
    /// region (row-major) or infinity, `triangle[i]` the index of its triangle
    /// or `u32::MAX`. Both buffers are resized to the region.
    pub fn render(
        &self,
        mesh: &TriangleMesh,
        camera_from_object: &Isometry3<f64>,
        region: PixelRegion,
        depth_m: &mut Vec<f32>,
        triangle: &mut Vec<u32>,
    ) {
        let region = self.clamped(region);
        depth_m.clear();
        depth_m.resize(region.len(), f32::INFINITY);
        triangle.clear();
        triangle.resize(region.len(), u32::MAX);
        let in_camera: Vec<Point3<f64>> = mesh.vertices.iter().map(|v| camera_from_object * v).collect();
        for (index, tri) in mesh.triangles.iter().enumerate() {
            let [a, b, c] = tri.map(|i| in_camera[i as usize]);
            if a.z < NEAR_M || b.z < NEAR_M || c.z < NEAR_M {
                continue;
            }
            if self.cull_back_faces && (b - a).cross(&(c - a)).dot(&a.coords) >= 0.0 {
                continue;
            }
            self.draw_triangle([a, b, c], index as u32, region, depth_m, triangle);
        }
    }

    /// `region` clipped to the image.
    fn clamped(&self, region: PixelRegion) -> PixelRegion {
        PixelRegion {
            u0: region.u0.min(self.width),
            v0: region.v0.min(self.height),
            u1: region.u1.min(self.width),
            v1: region.v1.min(self.height),
        }
    }

    fn draw_triangle(
        &self,
        corners: [Point3<f64>; 3],
        index: u32,
        region: PixelRegion,
        depth_m: &mut [f32],
        triangle: &mut [u32],
    ) {
        let project = |p: &Point3<f64>| (self.fx * p.x / p.z + self.cx, self.fy * p.y / p.z + self.cy);
        let [(x0, y0), (x1, y1), (x2, y2)] = corners.map(|p| project(&p));
        let area = (x1 - x0) * (y2 - y0) - (x2 - x0) * (y1 - y0);
        if area.abs() < 1e-12 {
            return;
        }
        let inv_z = corners.map(|p| 1.0 / p.z);
        let min_u = x0.min(x1).min(x2).ceil().max(f64::from(region.u0));
        let max_u = x0.max(x1).max(x2).floor().min(f64::from(region.u1) - 1.0);
        let min_v = y0.min(y1).min(y2).ceil().max(f64::from(region.v0));
        let max_v = y0.max(y1).max(y2).floor().min(f64::from(region.v1) - 1.0);
        if min_u > max_u || min_v > max_v {
            return;
        }
        let stride = region.width() as usize;
        for v in min_v as u32..=max_v as u32 {
            let py = f64::from(v);
            for u in min_u as u32..=max_u as u32 {
                let px = f64::from(u);
                // Barycentric coordinates from the signed areas.
                let w0 = ((x1 - px) * (y2 - py) - (x2 - px) * (y1 - py)) / area;
                let w1 = ((x2 - px) * (y0 - py) - (x0 - px) * (y2 - py)) / area;
                let w2 = 1.0 - w0 - w1;
                if w0 < -1e-9 || w1 < -1e-9 || w2 < -1e-9 {
                    continue;
                }
                let z = (1.0 / (w0 * inv_z[0] + w1 * inv_z[1] + w2 * inv_z[2])) as f32;
                let i = (v - region.v0) as usize * stride + (u - region.u0) as usize;
                if z < depth_m[i] {
                    depth_m[i] = z;
                    triangle[i] = index;
                }
            }
        }
    }

    /// The depth (m) of `mesh` at `camera_from_object` through each of
    /// `pixels`, `0` where the mesh is not seen (what ROFT's outlier test
    /// compares with the measured depth).
    pub fn depth_at(
        &self,
        mesh: &TriangleMesh,
        camera_from_object: &Isometry3<f64>,
        pixels: &[(u32, u32)],
        out: &mut Vec<f32>,
    ) {
        out.clear();
        let Some(region) = PixelRegion::around(pixels).map(|r| self.clamped(r)) else {
            return;
        };
        let (mut depth, mut triangle) = (Vec::new(), Vec::new());
        self.render(mesh, camera_from_object, region, &mut depth, &mut triangle);
        let stride = region.width() as usize;
        out.extend(pixels.iter().map(|&(u, v)| {
            if u < region.u0 || v < region.v0 || u >= region.u1 || v >= region.v1 {
                return 0.0;
            }
            let d = depth[(v - region.v0) as usize * stride + (u - region.u0) as usize];
            if d.is_finite() { d } else { 0.0 }
        }));
    }
}

#[cfg(test)]
mod tests {
    use nalgebra::{Isometry3, Translation3, UnitQuaternion};
    use slidetrack_core::CameraIntrinsics;

    use super::*;

    fn small_camera() -> CameraIntrinsics {
        CameraIntrinsics {
            width: 160,
            height: 120,
            fx: 140.0,
            fy: 140.0,
            cx: 79.5,
            cy: 59.5,
            distortion: [0.0; 5],
        }
    }

    #[test]
    fn a_face_on_box_has_the_depth_of_its_front_face() {
        let r = Rasterizer::new(&small_camera()).culling_back_faces();
        let mesh = TriangleMesh::cuboid([0.2, 0.2, 0.1]);
        let pose = Isometry3::from_parts(Translation3::new(0.0, 0.0, 0.6), UnitQuaternion::identity());
        let (mut depth, mut tri) = (Vec::new(), Vec::new());
        r.render(&mesh, &pose, PixelRegion::full(160, 120), &mut depth, &mut tri);
        // Centre pixel: the front face is at z = 0.6 - 0.05.
        let centre = 60 * 160 + 80;
        assert!((depth[centre] - 0.55).abs() < 1e-6);
        // The face spans ±0.1 m at 0.55 m: ±25.5 px around the centre.
        let row: Vec<bool> = (0..160).map(|u| depth[60 * 160 + u].is_finite()).collect();
        let first = row.iter().position(|b| *b).unwrap();
        let last = row.iter().rposition(|b| *b).unwrap();
        assert!((first as f64 - (79.5 - 0.1 / 0.55 * 140.0)).abs() <= 1.0, "{first}");
        assert!((last as f64 - (79.5 + 0.1 / 0.55 * 140.0)).abs() <= 1.0, "{last}");
        // depth_at agrees, and is 0 off the object.
        let mut out = Vec::new();
        r.depth_at(&mesh, &pose, &[(80, 60), (2, 2), (500, 500)], &mut out);
        assert!((out[0] - 0.55).abs() < 1e-6 && out[1] == 0.0 && out[2] == 0.0);
    }
}
