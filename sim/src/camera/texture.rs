//! The procedural background: smooth value noise under random rectangles and
//! bars, from a fixed seed, so the detector meets clutter and sharp edges.

use nalgebra::{Isometry3, Vector3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::config::BackgroundConfig;
use super::raster::{PixelRect, UndistortionMap, luma};

/// A rectangle painted on the plane, in plane coordinates (m).
struct Patch {
    a_range_m: (f64, f64),
    b_range_m: (f64, f64),
    rgb: [f32; 3],
}

/// The texture of the background plane.
pub(super) struct Texture {
    seed: u64,
    feature_size_m: f64,
    mean_rgb: [f32; 3],
    contrast: f32,
    patches: Vec<Patch>,
}

impl Texture {
    pub(super) fn new(config: &BackgroundConfig) -> Texture {
        let mut rng = ChaCha8Rng::seed_from_u64(config.texture_seed);
        let mean_rgb = config.mean_rgb.map(f32::from);
        let feature = config.feature_size_m;
        let patches = (0..config.clutter_count)
            .map(|_| {
                let centre = (rng.random_range(-0.35..0.35), rng.random_range(-0.25..0.25));
                // One in three is a thin bar (cables, table edges, text lines).
                let (half_a, half_b) = if rng.random_bool(1.0 / 3.0) {
                    let long = rng.random_range(3.0..20.0) * feature;
                    let thin = rng.random_range(0.1..0.4) * feature;
                    if rng.random_bool(0.5) { (long, thin) } else { (thin, long) }
                } else {
                    (rng.random_range(0.5..4.0) * feature, rng.random_range(0.5..4.0) * feature)
                };
                let shade = rng.random_range(0.15f32..1.9);
                let tint: [f32; 3] =
                    [rng.random_range(0.7..1.3), rng.random_range(0.7..1.3), rng.random_range(0.7..1.3)];
                let rgb = [0, 1, 2].map(|c| (mean_rgb[c] * shade * tint[c]).clamp(5.0, 250.0));
                Patch {
                    a_range_m: (centre.0 - half_a, centre.0 + half_a),
                    b_range_m: (centre.1 - half_b, centre.1 + half_b),
                    rgb,
                }
            })
            .collect();
        Texture {
            seed: config.texture_seed,
            feature_size_m: feature,
            mean_rgb,
            contrast: config.contrast as f32,
            patches,
        }
    }

    /// Colour (0..255 per channel) at plane point `(a, b)` (m).
    pub(super) fn colour(&self, a: f64, b: f64) -> [f32; 3] {
        if let Some(p) = self.patches.iter().rev().find(|p| {
            (p.a_range_m.0..p.a_range_m.1).contains(&a) && (p.b_range_m.0..p.b_range_m.1).contains(&b)
        }) {
            return p.rgb;
        }
        // Three octaves of value noise, coarse to fine, in [0, 1].
        let mut n = 0.0;
        let mut weight_sum = 0.0;
        for (octave, (scale, weight)) in [(8.0, 0.55), (3.0, 0.3), (1.0, 0.15)].into_iter().enumerate() {
            let cell = self.feature_size_m * scale;
            n += weight * value_noise(self.seed.wrapping_add(octave as u64), a / cell, b / cell);
            weight_sum += weight;
        }
        let gain = 1.0 + self.contrast * 2.0 * (n / weight_sum - 0.5) as f32;
        self.mean_rgb.map(|m| (m * gain).clamp(0.0, 255.0))
    }
}

/// Smoothly interpolated lattice noise in [0, 1].
fn value_noise(seed: u64, a: f64, b: f64) -> f64 {
    let (ia, ib) = (a.floor(), b.floor());
    let (fa, fb) = (smooth(a - ia), smooth(b - ib));
    let (ia, ib) = (ia as i64, ib as i64);
    let at = |da: i64, db: i64| lattice(seed, ia + da, ib + db);
    let top = at(0, 0) + (at(1, 0) - at(0, 0)) * fa;
    let bottom = at(0, 1) + (at(1, 1) - at(0, 1)) * fa;
    top + (bottom - top) * fb
}

fn smooth(t: f64) -> f64 {
    t * t * (3.0 - 2.0 * t)
}

fn lattice(seed: u64, ia: i64, ib: i64) -> f64 {
    let h = splitmix64(seed ^ splitmix64((ia as u64) ^ splitmix64(ib as u64).rotate_left(17)));
    (h >> 11) as f64 / (1u64 << 53) as f64
}

/// SplitMix64 finaliser: a well-mixed 64-bit hash.
pub(super) fn splitmix64(x: u64) -> u64 {
    let mut z = x.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// The background plane in the hand frame with two in-plane axes.
pub(super) struct BackgroundPlane {
    point_in_hand: Vector3<f64>,
    normal_in_hand: Vector3<f64>,
    axis_a: Vector3<f64>,
    axis_b: Vector3<f64>,
}

impl BackgroundPlane {
    /// `None` when the normal has no length (rejected by validation earlier).
    pub(super) fn new(config: &BackgroundConfig) -> Option<BackgroundPlane> {
        let normal = Vector3::from(config.normal_in_hand).try_normalize(1e-9)?;
        let helper = if normal.cross(&Vector3::z()).norm() > 1e-3 { Vector3::z() } else { Vector3::y() };
        let axis_a = helper.cross(&normal).normalize();
        let axis_b = normal.cross(&axis_a);
        Some(BackgroundPlane {
            point_in_hand: Vector3::from(config.point_in_hand_m),
            normal_in_hand: normal,
            axis_a,
            axis_b,
        })
    }

    /// Renders the background for every pixel (one ray per pixel centre):
    /// `channels` floats per pixel, 0..255.
    pub(super) fn render(
        &self,
        texture: &Texture,
        map: &UndistortionMap,
        hand_from_camera: &Isometry3<f64>,
        rect: PixelRect,
        channels: usize,
    ) -> Vec<f32> {
        let origin = hand_from_camera.translation.vector;
        let mut out = Vec::with_capacity(rect.width() * rect.height() * channels);
        for v in rect.y0..rect.y1 {
            for u in rect.x0..rect.x1 {
                let [x, y] = map.pixel_centre(u, v);
                let direction = hand_from_camera.rotation * Vector3::new(x, y, 1.0);
                let n_dot_d = self.normal_in_hand.dot(&direction);
                let lambda = self.normal_in_hand.dot(&(self.point_in_hand - origin)) / n_dot_d;
                let rgb = if n_dot_d.abs() > 1e-12 && lambda > 0.0 {
                    let q = origin + direction * lambda - self.point_in_hand;
                    texture.colour(q.dot(&self.axis_a), q.dot(&self.axis_b))
                } else {
                    texture.mean_rgb
                };
                if channels == 1 {
                    out.push(luma(rgb));
                } else {
                    out.extend_from_slice(&rgb);
                }
            }
        }
        out
    }
}
