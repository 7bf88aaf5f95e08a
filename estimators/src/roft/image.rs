//! The image-shaped inputs of ROFT, as plain data: pinhole intrinsics, depth
//! maps, pixel masks and optical-flow fields.

use std::sync::Arc;

/// Pinhole intrinsics of an undistorted (registered) RGB-D camera, px.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pinhole {
    /// Image width (px).
    pub width: u32,
    /// Image height (px).
    pub height: u32,
    /// Focal length along x (px).
    pub fx: f64,
    /// Focal length along y (px).
    pub fy: f64,
    /// Principal point x (px).
    pub cx: f64,
    /// Principal point y (px).
    pub cy: f64,
}

impl Pinhole {
    /// The point `p_uv(d)` of pixel `(u, v)` at depth `d` (m), camera frame (3.28).
    pub fn back_project(&self, u: f64, v: f64, depth_m: f64) -> [f64; 3] {
        [(u - self.cx) / self.fx * depth_m, (v - self.cy) / self.fy * depth_m, depth_m]
    }

    /// The pixel of a point in the camera frame (3.36); `None` behind the camera.
    pub fn project(&self, p: [f64; 3]) -> Option<(f64, f64)> {
        (p[2] > 1e-9).then(|| (self.cx + p[0] / p[2] * self.fx, self.cy + p[1] / p[2] * self.fy))
    }

    /// All numbers positive and finite.
    pub fn is_valid(&self) -> bool {
        self.width > 0
            && self.height > 0
            && [self.fx, self.fy].iter().all(|f| *f > 0.0 && f.is_finite())
            && [self.cx, self.cy].iter().all(|c| c.is_finite())
    }
}

/// A depth image in metres, row-major; `0` (or any non-positive or
/// non-finite value) is an invalid pixel.
#[derive(Clone, Debug, PartialEq)]
pub struct DepthMap {
    /// Width (px).
    pub width: u32,
    /// Height (px).
    pub height: u32,
    /// `width * height` depths (m).
    pub depth_m: Vec<f32>,
}

impl DepthMap {
    /// A map of invalid pixels.
    pub fn invalid(width: u32, height: u32) -> DepthMap {
        DepthMap { width, height, depth_m: vec![0.0; width as usize * height as usize] }
    }

    /// The valid depth at `(u, v)` (m), `None` when invalid or outside.
    pub fn at(&self, u: u32, v: u32) -> Option<f64> {
        if u >= self.width || v >= self.height {
            return None;
        }
        let d = *self.depth_m.get(v as usize * self.width as usize + u as usize)?;
        (d > 0.0 && d.is_finite()).then_some(f64::from(d))
    }
}

/// A rectangle of pixels, `[u0, u1) x [v0, v1)`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PixelBox {
    /// First column.
    pub u0: u32,
    /// First row.
    pub v0: u32,
    /// One past the last column.
    pub u1: u32,
    /// One past the last row.
    pub v1: u32,
}

impl PixelBox {
    /// Grown by `margin` px on every side, clipped to `width x height`.
    pub fn grown(&self, margin: u32, width: u32, height: u32) -> PixelBox {
        PixelBox {
            u0: self.u0.saturating_sub(margin),
            v0: self.v0.saturating_sub(margin),
            u1: self.u1.saturating_add(margin).min(width),
            v1: self.v1.saturating_add(margin).min(height),
        }
    }

    /// Width (px).
    pub fn width(&self) -> u32 {
        self.u1.saturating_sub(self.u0)
    }

    /// Height (px).
    pub fn height(&self) -> u32 {
        self.v1.saturating_sub(self.v0)
    }
}

/// A set of pixels (the object segmentation mask `M`), as a bitmap.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Mask {
    width: u32,
    height: u32,
    inside: Vec<bool>,
}

impl Mask {
    /// An empty mask.
    pub fn empty(width: u32, height: u32) -> Mask {
        Mask { width, height, inside: vec![false; width as usize * height as usize] }
    }

    /// A mask from bytes, non-zero meaning inside; `None` when the length is
    /// not `width * height`.
    pub fn from_bytes(width: u32, height: u32, bytes: &[u8]) -> Option<Mask> {
        (bytes.len() == width as usize * height as usize).then(|| Mask {
            width,
            height,
            inside: bytes.iter().map(|b| *b != 0).collect(),
        })
    }

    /// Width (px).
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Height (px).
    pub fn height(&self) -> u32 {
        self.height
    }

    /// Whether `(u, v)` is in the mask.
    pub fn contains(&self, u: u32, v: u32) -> bool {
        u < self.width && v < self.height && self.inside[v as usize * self.width as usize + u as usize]
    }

    /// Adds `(u, v)` (ignored outside the image).
    pub fn insert(&mut self, u: u32, v: u32) {
        if u < self.width && v < self.height {
            self.inside[v as usize * self.width as usize + u as usize] = true;
        }
    }

    /// Number of pixels in the mask.
    pub fn count(&self) -> usize {
        self.inside.iter().filter(|b| **b).count()
    }

    /// No pixel in the mask.
    pub fn is_empty(&self) -> bool {
        !self.inside.iter().any(|b| *b)
    }

    /// The pixels, row by row.
    pub fn pixels(&self) -> impl Iterator<Item = (u32, u32)> + '_ {
        let w = self.width as usize;
        self.inside
            .iter()
            .enumerate()
            .filter(|(_, b)| **b)
            .map(move |(i, _)| ((i % w) as u32, (i / w) as u32))
    }

    /// The smallest box holding the mask, `None` when empty.
    pub fn bounding_box(&self) -> Option<PixelBox> {
        let mut b: Option<PixelBox> = None;
        for (u, v) in self.pixels() {
            let r = b.get_or_insert(PixelBox { u0: u, v0: v, u1: u + 1, v1: v + 1 });
            r.u0 = r.u0.min(u);
            r.v0 = r.v0.min(v);
            r.u1 = r.u1.max(u + 1);
            r.v1 = r.v1.max(v + 1);
        }
        b
    }

    /// As bytes, 255 inside and 0 outside.
    pub fn to_bytes(&self) -> Vec<u8> {
        self.inside.iter().map(|b| if *b { 255 } else { 0 }).collect()
    }
}

/// Dense optical flow from frame `t-1` to frame `t` over a region of the
/// image: `(Δu, Δv)` (px) of the pixel `(u, v)` of frame `t-1` (3.33)-(3.35).
/// Outside the region, or where a component is not finite, the flow is unknown.
#[derive(Clone, Debug, PartialEq)]
pub struct FlowField {
    /// The region the flow was computed on.
    pub region: PixelBox,
    /// `region.width() * region.height()` displacements (px), row-major.
    pub flow_px: Vec<[f32; 2]>,
}

impl FlowField {
    /// The flow at `(u, v)`, `None` when unknown.
    pub fn at(&self, u: u32, v: u32) -> Option<[f32; 2]> {
        let r = &self.region;
        if u < r.u0 || u >= r.u1 || v < r.v0 || v >= r.v1 {
            return None;
        }
        let f = *self.flow_px.get((v - r.v0) as usize * r.width() as usize + (u - r.u0) as usize)?;
        (f[0].is_finite() && f[1].is_finite()).then_some(f)
    }
}

/// A shared flow field (the mask synchroniser keeps recent ones).
pub type SharedFlow = Arc<FlowField>;
