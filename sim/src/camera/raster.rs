//! Ray casting onto planes, anti-aliasing, blur, noise and quantisation.
//!
//! Pixel coordinates follow OpenCV: pixel `(u, v)` has its centre at the
//! integer position and covers `[u - 0.5, u + 0.5] x [v - 0.5, v + 0.5]`.

use nalgebra::{Isometry3, Vector3};
use slidetrack_core::CameraIntrinsics;

/// Fixed-point scale of the noise and background buffers: 16 units per gray level.
pub(super) const FIXED_ONE: f32 = 16.0;

/// Undistorted normalised ray directions `(X/Z, Y/Z)` at every pixel corner.
pub(super) struct UndistortionMap {
    width: usize,
    /// `(width + 1) * (height + 1)` entries; entry `(i, j)` is the corner at
    /// pixel position `(i - 0.5, j - 0.5)`.
    corners: Vec<[f32; 2]>,
}

impl UndistortionMap {
    /// Inverts the distortion at every pixel corner (once per camera).
    pub(super) fn new(intrinsics: &CameraIntrinsics) -> UndistortionMap {
        let width = intrinsics.width as usize;
        let height = intrinsics.height as usize;
        let mut corners = Vec::with_capacity((width + 1) * (height + 1));
        for j in 0..=height {
            for i in 0..=width {
                let (x, y) = intrinsics.undistort_pixel(i as f64 - 0.5, j as f64 - 0.5);
                corners.push([x as f32, y as f32]);
            }
        }
        UndistortionMap { width, corners }
    }

    /// Image width (px).
    pub(super) fn width(&self) -> usize {
        self.width
    }

    /// The ray at corner `(i, j)`, `i <= width`, `j <= height`.
    pub(super) fn corner(&self, i: usize, j: usize) -> [f64; 2] {
        let [x, y] = self.corners[j * (self.width + 1) + i];
        [f64::from(x), f64::from(y)]
    }

    /// The ray through the centre of pixel `(u, v)`: the mean of its corners
    /// (the map is smooth, so this is exact to far below a pixel).
    pub(super) fn pixel_centre(&self, u: usize, v: usize) -> [f64; 2] {
        let corners =
            [self.corner(u, v), self.corner(u + 1, v), self.corner(u, v + 1), self.corner(u + 1, v + 1)];
        let sum = corners.iter().fold([0.0, 0.0], |s, c| [s[0] + c[0], s[1] + c[1]]);
        [sum[0] / 4.0, sum[1] / 4.0]
    }

    /// Largest `|x|` or `|y|` over the image: rays beyond it are off-image.
    pub(super) fn half_extent(&self) -> f64 {
        self.corners.iter().map(|&[x, y]| f64::from(x.abs().max(y.abs()))).fold(0.0, f64::max)
    }
}

/// A rectangle of pixels, `x0..x1` by `y0..y1` (ends exclusive).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct PixelRect {
    pub x0: usize,
    pub y0: usize,
    pub x1: usize,
    pub y1: usize,
}

impl PixelRect {
    pub(super) fn full(width: usize, height: usize) -> PixelRect {
        PixelRect { x0: 0, y0: 0, x1: width, y1: height }
    }
    pub(super) fn width(&self) -> usize {
        self.x1 - self.x0
    }
    pub(super) fn height(&self) -> usize {
        self.y1 - self.y0
    }
    pub(super) fn is_empty(&self) -> bool {
        self.x1 <= self.x0 || self.y1 <= self.y0
    }
    /// Grown by `margin` px on every side, clipped to the image.
    pub(super) fn grown(&self, margin: usize, width: usize, height: usize) -> PixelRect {
        PixelRect {
            x0: self.x0.saturating_sub(margin),
            y0: self.y0.saturating_sub(margin),
            x1: (self.x1 + margin).min(width),
            y1: (self.y1 + margin).min(height),
        }
    }
}

/// A plane in the camera frame, from a pose whose x, y axes span the plane.
///
/// For the ray `d = (x, y, 1)` the hit point is `lambda d` with `lambda = (n .
/// o) / (n . d)`, and its plane coordinates are `a = (alpha_a . d) / (n . d)`,
/// `b = (alpha_b . d) / (n . d)` with `alpha_a = (n . o) e_a - (o . e_a) n`
/// (same for b): a homography from normalised image coordinates.
pub(super) struct PlaneInCamera {
    origin: Vector3<f64>,
    axis_a: Vector3<f64>,
    axis_b: Vector3<f64>,
    normal: Vector3<f64>,
    alpha_a: Vector3<f64>,
    alpha_b: Vector3<f64>,
    /// `normal . origin`: negative when the plane's +z side faces the camera.
    normal_dot_origin: f64,
    two_sided: bool,
}

impl PlaneInCamera {
    /// The plane z = 0 of `camera_from_plane`. One-sided planes are seen only
    /// from their +z side.
    pub(super) fn new(camera_from_plane: &Isometry3<f64>, two_sided: bool) -> PlaneInCamera {
        let r = camera_from_plane.rotation.to_rotation_matrix();
        let origin = camera_from_plane.translation.vector;
        let axis_a = r.matrix().column(0).into_owned();
        let axis_b = r.matrix().column(1).into_owned();
        let normal = r.matrix().column(2).into_owned();
        let normal_dot_origin = normal.dot(&origin);
        PlaneInCamera {
            alpha_a: axis_a * normal_dot_origin - normal * origin.dot(&axis_a),
            alpha_b: axis_b * normal_dot_origin - normal * origin.dot(&axis_b),
            origin,
            axis_a,
            axis_b,
            normal,
            normal_dot_origin,
            two_sided,
        }
    }

    /// Whether the camera sees the visible side of the plane.
    pub(super) fn faces_camera(&self) -> bool {
        self.two_sided || self.normal_dot_origin < 0.0
    }

    /// Plane coordinates `(a, b)` (m) where the ray `(x, y, 1)` meets the plane,
    /// or `None` when it meets it behind the camera or from the hidden side.
    #[inline]
    pub(super) fn hit(&self, x: f64, y: f64) -> Option<(f64, f64)> {
        let (n, aa, ab) = (&self.normal, &self.alpha_a, &self.alpha_b);
        let n_dot_d = n.x * x + n.y * y + n.z;
        // lambda > 0 needs n.d of the sign of n.o; a one-sided plane needs n.d < 0.
        let visible = if self.two_sided {
            n_dot_d * self.normal_dot_origin > 0.0
        } else {
            n_dot_d < 0.0 && self.normal_dot_origin < 0.0
        };
        if !visible {
            return None;
        }
        let inv = 1.0 / n_dot_d;
        Some(((aa.x * x + aa.y * y + aa.z) * inv, (ab.x * x + ab.y * y + ab.z) * inv))
    }

    /// The plane's +z axis in the camera frame.
    pub(super) fn normal(&self) -> Vector3<f64> {
        self.normal
    }

    /// A point of the plane in the camera frame.
    pub(super) fn point(&self, a: f64, b: f64) -> Vector3<f64> {
        self.origin + self.axis_a * a + self.axis_b * b
    }
}

/// Pixel bounding box of a planar polygon (plane coordinates, m). The polygon
/// is first clipped to a viewing frustum slightly wider than the image
/// (`frustum_half_size` in normalised coordinates), where the distortion
/// polynomial is monotonic, then its edges are sampled so that
/// distortion-curved edges stay inside. `None` when nothing is in view.
pub(super) fn outline_bbox(
    intrinsics: &CameraIntrinsics,
    plane: &PlaneInCamera,
    polygon: &[(f64, f64)],
    frustum_half_size: f64,
) -> Option<PixelRect> {
    const STEPS: usize = 16;
    let corners: Vec<Vector3<f64>> = polygon.iter().map(|&(a, b)| plane.point(a, b)).collect();
    let clipped = clip_to_frustum(corners, frustum_half_size);
    if clipped.len() < 3 {
        return None;
    }
    let (width, height) = (intrinsics.width as usize, intrinsics.height as usize);
    let (mut u_min, mut v_min, mut u_max, mut v_max) = (f64::MAX, f64::MAX, f64::MIN, f64::MIN);
    for (k, p0) in clipped.iter().enumerate() {
        let p1 = clipped[(k + 1) % clipped.len()];
        for s in 0..STEPS {
            let p = p0 + (p1 - p0) * (s as f64 / STEPS as f64);
            let (u, v) = intrinsics.project([p.x, p.y, p.z])?;
            u_min = u_min.min(u);
            v_min = v_min.min(v);
            u_max = u_max.max(u);
            v_max = v_max.max(v);
        }
    }
    // Pixel u covers [u - 0.5, u + 0.5]; keep one extra pixel for safety.
    let x0 = (u_min - 1.5).floor().max(0.0) as usize;
    let y0 = (v_min - 1.5).floor().max(0.0) as usize;
    let x1 = ((u_max + 2.5).ceil().max(0.0) as usize).min(width);
    let y1 = ((v_max + 2.5).ceil().max(0.0) as usize).min(height);
    let rect = PixelRect { x0, y0, x1, y1 };
    (!rect.is_empty()).then_some(rect)
}

/// Sutherland-Hodgman clipping of a convex polygon (camera frame) to
/// `z >= 1e-6` and `|x|, |y| <= half_size * z`.
fn clip_to_frustum(mut polygon: Vec<Vector3<f64>>, half_size: f64) -> Vec<Vector3<f64>> {
    let planes: [fn(&Vector3<f64>, f64) -> f64; 5] = [
        |p, _| p.z - 1e-6,
        |p, h| h * p.z - p.x,
        |p, h| h * p.z + p.x,
        |p, h| h * p.z - p.y,
        |p, h| h * p.z + p.y,
    ];
    for inside in planes {
        let mut out = Vec::with_capacity(polygon.len() + 2);
        for (k, p) in polygon.iter().enumerate() {
            let q = polygon[(k + 1) % polygon.len()];
            let (dp, dq) = (inside(p, half_size), inside(&q, half_size));
            if dp >= 0.0 {
                out.push(*p);
            }
            if (dp >= 0.0) != (dq >= 0.0) {
                out.push(p + (q - p) * (dp / (dp - dq)));
            }
        }
        polygon = out;
        if polygon.is_empty() {
            break;
        }
    }
    polygon
}

/// Rec. 601 luma of an sRGB colour (0..255).
pub(super) fn luma(rgb: [f32; 3]) -> f32 {
    0.299 * rgb[0] + 0.587 * rgb[1] + 0.114 * rgb[2]
}

/// Normalised 1-D Gaussian kernel of standard deviation `sigma_px`, radius
/// `ceil(2.5 sigma)` (the tail beyond holds 1.2 % of the weight); a single tap
/// when blur is off.
pub(super) fn gaussian_kernel(sigma_px: f64) -> Vec<f32> {
    if sigma_px < 0.05 {
        return vec![1.0];
    }
    let radius = (2.5 * sigma_px).ceil() as i64;
    let taps: Vec<f64> =
        (-radius..=radius).map(|k| (-(k * k) as f64 / (2.0 * sigma_px * sigma_px)).exp()).collect();
    let total: f64 = taps.iter().sum();
    taps.iter().map(|t| (t / total) as f32).collect()
}

/// Separable blur of a `w x h x channels` buffer in place, edges clamped.
/// Both passes run as one multiply-add per tap over whole rows, which the
/// compiler vectorises.
pub(super) fn blur<const C: usize>(buf: &mut [f32], w: usize, h: usize, kernel: &[f32], tmp: &mut Vec<f32>) {
    let channels = C;
    if kernel.len() <= 1 || w == 0 || h == 0 {
        return;
    }
    let r = kernel.len() / 2;
    let stride = w * channels;
    // Horizontal pass: each row, padded by `r` clamped pixels on both sides, into tmp.
    tmp.clear();
    tmp.resize(buf.len(), 0.0);
    let mut padded = vec![0.0f32; (w + 2 * r) * channels];
    for y in 0..h {
        let row = &buf[y * stride..(y + 1) * stride];
        let (first, last) = (&row[..C], &row[stride - C..]);
        padded[..r * C].chunks_exact_mut(C).for_each(|px| px.copy_from_slice(first));
        padded[r * C..r * C + stride].copy_from_slice(row);
        padded[r * C + stride..].chunks_exact_mut(C).for_each(|px| px.copy_from_slice(last));
        let out = &mut tmp[y * stride..(y + 1) * stride];
        for (t, &k) in kernel.iter().enumerate() {
            let src = &padded[t * channels..t * channels + stride];
            out.iter_mut().zip(src).for_each(|(o, s)| *o += k * s);
        }
    }
    // Vertical pass: tmp -> buf, one output row at a time.
    for y in 0..h {
        let out = &mut buf[y * stride..(y + 1) * stride];
        out.iter_mut().for_each(|v| *v = 0.0);
        for (t, &k) in kernel.iter().enumerate() {
            let ys = (y + t).saturating_sub(r).min(h - 1);
            let src = &tmp[ys * stride..(ys + 1) * stride];
            out.iter_mut().zip(src).for_each(|(o, s)| *o += k * s);
        }
    }
}

/// A gray level (0..255) in fixed point.
#[inline]
pub(super) fn to_fixed(value: f32) -> i16 {
    // Values are clamped non-negative first, so truncation after +0.5 rounds.
    (value * FIXED_ONE + 0.5).clamp(0.0, 255.0 * FIXED_ONE) as i16
}

/// `clamp(round((scene + noise) / 16), 0, 255)` element-wise, in 16-bit
/// arithmetic (scene <= 4080 and |noise| <= 8191 cannot overflow).
#[inline]
pub(super) fn quantise(scene_fixed: &[i16], noise_fixed: &[i16], out: &mut [u8]) {
    for ((o, &s), &n) in out.iter_mut().zip(scene_fixed).zip(noise_fixed) {
        *o = quantise_one(s, n);
    }
}

/// One byte of [`quantise`].
#[inline]
pub(super) fn quantise_one(scene_fixed: i16, noise_fixed: i16) -> u8 {
    ((scene_fixed + noise_fixed + 8) >> 4).clamp(0, 255) as u8
}
