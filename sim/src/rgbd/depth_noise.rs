//! [`DepthNoise`]: the depth sensor's imperfections, and how a rendered
//! depth map is turned into the sensor's integer millimetres.
//!
//! The model is that of a triangulating sensor (structured light, like the
//! Kinect v1 whose noise it was measured on, or active stereo): depth comes
//! from a disparity `d = f b / z` (px), found by matching a window of pixels,
//! so
//! - the error is a disparity error, `σ_d = σ_z(z) f b / z²`, with the
//!   measured axial noise `σ_z(z) = 0.0012 + 0.0019 (z - 0.4)²` m of Nguyen,
//!   Izadi and Lovell (2012), "Modeling Kinect Sensor Noise for Improved 3D
//!   Reconstruction and Tracking", 3DIMPVT;
//! - neighbouring pixels share their matching window and so their error: the
//!   error is a smooth random field (a Gaussian lattice every
//!   `correlation_px` pixels, bilinearly interpolated, rescaled to unit
//!   variance at every pixel), not independent per pixel;
//! - the disparity is reported in whole sub-pixel steps (`disparity_step_px`),
//!   so depth takes discrete levels `f b / (k · step)` whose spacing grows
//!   with `z²` (Khoshelham and Oude Elberink (2012), "Accuracy and Resolution
//!   of Kinect Depth Data for Indoor Mapping Applications", Sensors 12(2)
//!   1437: "the low resolution of the depth measurements").
//!
//! `correlation_px = 1` and `disparity_step_px = 0` give the independent,
//! unquantised noise of earlier versions.

use serde::{Deserialize, Serialize};
use slidetrack_core::DepthImage;

/// The depth sensor's imperfections.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DepthNoise {
    /// Noise standard deviation `σ(z) = base + quadratic * (z - 0.4 m)²` (m):
    /// the axial noise model of structured-light sensors (Nguyen et al. 2012).
    pub base_m: f64,
    /// See `base_m` (1/m).
    pub quadratic_per_m: f64,
    /// Distance between the projector (or the other camera) and the depth
    /// camera (m): with the focal length, it turns depth into disparity.
    pub baseline_m: f64,
    /// Disparity resolution (px); 0 leaves the disparity unquantised.
    pub disparity_step_px: f64,
    /// Spacing of the error field's lattice (px): pixels closer than this
    /// share much of their error; 1 makes it independent per pixel.
    pub correlation_px: u32,
    /// Probability that a pixel has no depth, anywhere.
    pub dropout: f64,
    /// Probability that a pixel on a depth edge (object border) has no depth.
    pub edge_dropout: f64,
    /// Surfaces seen at `|cos(angle)|` below this have no depth.
    pub grazing_cos: f64,
}

impl Default for DepthNoise {
    /// A Kinect-v1-like sensor: its measured axial noise, a 7.5 cm baseline,
    /// 1/8 px disparity steps (4.9 mm apart at 1.3 m with a 554 px focal
    /// length), an error field correlated over 8 px.
    fn default() -> DepthNoise {
        DepthNoise {
            base_m: 0.0012,
            quadratic_per_m: 0.0019,
            baseline_m: 0.075,
            disparity_step_px: 0.125,
            correlation_px: 8,
            dropout: 0.01,
            edge_dropout: 0.5,
            grazing_cos: 0.12,
        }
    }
}

/// What [`DepthNoise::apply`] needs to know of the rendered frame.
pub(super) struct CleanDepth<'a> {
    /// Width and height (px).
    pub size: (usize, usize),
    /// Focal length (px) along the baseline.
    pub fx: f64,
    /// Rendered depth (m), row-major.
    pub depth_m: &'a [f32],
    /// 255 on the object.
    pub mask: &'a [u8],
    /// `|cos|` of the angle between the ray and the surface normal.
    pub normal_cos: &'a [f32],
}

impl DepthNoise {
    /// Standard normal values this model draws per frame of `w x h` px.
    pub(super) fn normals_needed(&self, w: usize, h: usize) -> usize {
        let l = self.correlation_px.max(1) as usize;
        if l == 1 { w * h } else { (w / l + 2) * (h / l + 2) }
    }

    /// The sensor's millimetres for `clean`, with `normals` (at least
    /// [`DepthNoise::normals_needed`] standard normal values) and `uniform`
    /// (one in 0..1 per pixel) as the frame's randomness.
    pub(super) fn apply(&self, clean: &CleanDepth, normals: &[f32], uniform: &[f32]) -> DepthImage {
        let (w, h) = clean.size;
        let fb = clean.fx * self.baseline_m;
        let field = ErrorField::new(self.correlation_px, w, normals);
        let mut data = vec![0u16; w * h];
        for y in 0..h {
            for x in 0..w {
                let i = y * w + x;
                let z = f64::from(clean.depth_m[i]);
                let m = clean.mask;
                let edge = (x > 0 && m[i - 1] != m[i])
                    || (x + 1 < w && m[i + 1] != m[i])
                    || (y > 0 && m[i - w] != m[i])
                    || (y + 1 < h && m[i + w] != m[i]);
                let p = f64::from(uniform[i]);
                let dropped = p < self.dropout
                    || (edge && p < self.dropout + self.edge_dropout)
                    || f64::from(clean.normal_cos[i]) < self.grazing_cos;
                if dropped || !z.is_finite() || z <= 0.0 {
                    continue;
                }
                let sigma_z = self.base_m + self.quadratic_per_m * (z - 0.4).powi(2);
                let n = field.at(x, y);
                let measured = if fb > 0.0 && self.disparity_step_px > 0.0 {
                    let d = fb / z + sigma_z * fb / (z * z) * n;
                    let steps = (d / self.disparity_step_px).round();
                    if steps < 1.0 {
                        continue;
                    }
                    fb / (steps * self.disparity_step_px)
                } else {
                    z + sigma_z * n
                };
                let mm = (measured * 1000.0).round();
                if mm >= 1.0 && mm <= f64::from(u16::MAX) {
                    data[i] = mm as u16;
                }
            }
        }
        DepthImage { width: w as u32, height: h as u32, data, scale_m: 0.001 }
    }
}

/// A unit-variance random field: independent normals on a lattice every
/// `spacing` px, bilinearly interpolated and rescaled by the weights' norm.
struct ErrorField<'a> {
    spacing: usize,
    columns: usize,
    lattice: &'a [f32],
}

impl ErrorField<'_> {
    fn new(spacing: u32, width: usize, lattice: &[f32]) -> ErrorField<'_> {
        let spacing = spacing.max(1) as usize;
        let columns = if spacing == 1 { width } else { width / spacing + 2 };
        ErrorField { spacing, columns, lattice }
    }

    fn at(&self, x: usize, y: usize) -> f64 {
        let l = self.spacing;
        if l == 1 {
            return f64::from(self.lattice[y * self.columns + x]);
        }
        let (gx, gy) = (x / l, y / l);
        let fx = (x % l) as f64 / l as f64;
        let fy = (y % l) as f64 / l as f64;
        let g = |cx: usize, cy: usize| f64::from(self.lattice[cy * self.columns + cx]);
        let v = g(gx, gy) * (1.0 - fx) * (1.0 - fy)
            + g(gx + 1, gy) * fx * (1.0 - fy)
            + g(gx, gy + 1) * (1.0 - fx) * fy
            + g(gx + 1, gy + 1) * fx * fy;
        let norm = (((1.0 - fx).powi(2) + fx * fx) * ((1.0 - fy).powi(2) + fy * fy)).sqrt();
        v / norm
    }
}
