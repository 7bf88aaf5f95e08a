//! The texture of the object's surface along the line each fingertip slides on.

use rand::RngExt;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

/// Statistics of the surface texture of an object.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SurfaceConfig {
    /// Root-mean-square height of the texture (m).
    pub roughness_rms_m: f64,
    /// Shortest and longest wavelength of the texture (m).
    pub wavelength_range_m: [f64; 2],
}

impl Default for SurfaceConfig {
    fn default() -> Self {
        SurfaceConfig { roughness_rms_m: 8e-6, wavelength_range_m: [0.002, 0.012] }
    }
}

/// A smooth random height profile `h(s)` (m) along the sliding line, a sum
/// of sinusoids with random wavelengths and phases.
#[derive(Clone, Debug, PartialEq)]
pub struct SurfaceProfile {
    /// `(amplitude m, wavenumber rad/m, phase rad)` per component.
    waves: Vec<(f64, f64, f64)>,
}

impl SurfaceProfile {
    /// Number of sinusoids in a profile.
    const WAVES: usize = 6;

    /// Draws a profile with the given statistics.
    pub fn draw(cfg: &SurfaceConfig, rng: &mut ChaCha8Rng) -> SurfaceProfile {
        let [lo, hi] = cfg.wavelength_range_m;
        // Equal power per component: rms = amplitude * sqrt(n / 2).
        let amplitude = cfg.roughness_rms_m * (2.0 / Self::WAVES as f64).sqrt();
        let waves = (0..Self::WAVES)
            .map(|_| {
                let wavelength = lo * (hi / lo).powf(rng.random::<f64>());
                let phase = rng.random_range(0.0..std::f64::consts::TAU);
                (amplitude, std::f64::consts::TAU / wavelength, phase)
            })
            .collect();
        SurfaceProfile { waves }
    }

    /// A flat surface.
    pub fn flat() -> SurfaceProfile {
        SurfaceProfile { waves: Vec::new() }
    }

    /// Height (m) and slope (dimensionless) at arc length `s_m`.
    pub fn height_and_slope(&self, s_m: f64) -> (f64, f64) {
        self.waves.iter().fold((0.0, 0.0), |(h, dh), &(a, k, phi)| {
            let (sin, cos) = (k * s_m + phi).sin_cos();
            (h + a * sin, dh + a * k * cos)
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn slope_is_the_derivative_of_height() {
        let p = SurfaceProfile::draw(&SurfaceConfig::default(), &mut ChaCha8Rng::seed_from_u64(4));
        for s in [0.0, 0.0123, 0.05] {
            let eps = 1e-7;
            let numeric = (p.height_and_slope(s + eps).0 - p.height_and_slope(s - eps).0) / (2.0 * eps);
            assert!((numeric - p.height_and_slope(s).1).abs() < 1e-6);
        }
    }

    #[test]
    fn rms_height_matches_the_configuration() {
        let cfg = SurfaceConfig::default();
        let p = SurfaceProfile::draw(&cfg, &mut ChaCha8Rng::seed_from_u64(5));
        let n = 20000;
        let ms: f64 = (0..n).map(|i| p.height_and_slope(i as f64 * 1e-5).0.powi(2)).sum::<f64>() / n as f64;
        assert!((ms.sqrt() / cfg.roughness_rms_m - 1.0).abs() < 0.2, "{}", ms.sqrt());
    }
}
