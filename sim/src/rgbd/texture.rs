//! Procedural textures: rich, non-repeating colour detail so that optical
//! flow has something to follow, generated from a seed.

use slidetrack_render::splitmix64;

/// A square, tiling RGB texture sampled with bilinear interpolation; texture
/// coordinates are in metres on the surface, one tile spanning `tile_m`.
#[derive(Clone, Debug, PartialEq)]
pub struct Texture {
    size: usize,
    tile_m: f64,
    /// `size * size` texels, linear RGB in `0..=1`.
    texels: Vec<[f32; 3]>,
}

impl Texture {
    /// Value noise in three octaves over two base colours, with a sprinkle
    /// of dark and bright specks: a texture like printed packaging.
    pub fn packaging(seed: u64, base: [f32; 3], accent: [f32; 3], tile_m: f64) -> Texture {
        let size = 256usize;
        let octaves = [(8usize, 0.55f32), (32, 0.3), (128, 0.15)];
        let lattices: Vec<Vec<f32>> = octaves
            .iter()
            .enumerate()
            .map(|(o, (n, _))| {
                (0..n * n).map(|i| unit(seed ^ splitmix64((o as u64) << 40 | i as u64))).collect()
            })
            .collect();
        let mut texels = Vec::with_capacity(size * size);
        for y in 0..size {
            for x in 0..size {
                let mut value = 0.0f32;
                for ((n, weight), lattice) in octaves.iter().zip(&lattices) {
                    value += weight
                        * lattice_sample(
                            lattice,
                            *n,
                            x as f32 * *n as f32 / size as f32,
                            y as f32 * *n as f32 / size as f32,
                        );
                }
                let speck = unit(seed ^ splitmix64(0xabcd_0000_0000 | (y * size + x) as u64));
                let mut rgb = [0.0f32; 3];
                for c in 0..3 {
                    rgb[c] = base[c] * (1.0 - value) + accent[c] * value;
                }
                if speck > 0.985 {
                    rgb = [0.95, 0.95, 0.9];
                } else if speck < 0.015 {
                    rgb = [0.05, 0.05, 0.08];
                }
                texels.push(rgb);
            }
        }
        Texture { size, tile_m, texels }
    }

    /// The colour at surface coordinates `(s, t)` (m).
    pub fn sample(&self, s_m: f64, t_m: f64) -> [f32; 3] {
        let scale = self.size as f64 / self.tile_m;
        let (x, y) = (s_m * scale, t_m * scale);
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = ((x - x0) as f32, (y - y0) as f32);
        let n = self.size as i64;
        let wrap = |v: f64| ((v as i64).rem_euclid(n)) as usize;
        let (xa, xb, ya, yb) = (wrap(x0), wrap(x0 + 1.0), wrap(y0), wrap(y0 + 1.0));
        let t = |xi: usize, yi: usize| self.texels[yi * self.size + xi];
        let (a, b, c, d) = (t(xa, ya), t(xb, ya), t(xa, yb), t(xb, yb));
        let mut out = [0.0f32; 3];
        for k in 0..3 {
            let top = a[k] + (b[k] - a[k]) * fx;
            let bottom = c[k] + (d[k] - c[k]) * fx;
            out[k] = top + (bottom - top) * fy;
        }
        out
    }
}

/// A uniform number in `[0, 1)` from a hash.
fn unit(h: u64) -> f32 {
    (splitmix64(h) >> 40) as f32 / (1u64 << 24) as f32
}

/// Smoothstep-interpolated value noise on an `n x n` tiling lattice.
fn lattice_sample(lattice: &[f32], n: usize, x: f32, y: f32) -> f32 {
    let (x0, y0) = (x.floor(), y.floor());
    let smooth = |f: f32| f * f * (3.0 - 2.0 * f);
    let (fx, fy) = (smooth(x - x0), smooth(y - y0));
    let at = |i: f32, j: f32| lattice[(j as usize % n) * n + (i as usize % n)];
    let top = at(x0, y0) + (at(x0 + 1.0, y0) - at(x0, y0)) * fx;
    let bottom = at(x0, y0 + 1.0) + (at(x0 + 1.0, y0 + 1.0) - at(x0, y0 + 1.0)) * fx;
    top + (bottom - top) * fy
}
