//! A uSkin-style 3-axis magnetic tactile module on a fingertip.
//!
//! A magnet sits in the silicone above a Hall-effect chip. Indentation brings
//! the magnet closer (the normal field grows like the inverse cube of the
//! distance), shear moves it sideways. The three field components reach the
//! chip through the module's mounting rotation and some cross-talk, on top of
//! a per-grasp baseline that drifts slowly, with white noise, vibration while
//! the object slides, u16 quantisation and rare spikes.

use nalgebra::{Matrix3, Rotation3, Vector3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use serde::{Deserialize, Serialize};

/// Parameters of the tactile modules (the same design on every finger; the
/// per-finger mounting differs).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TactileModelConfig {
    /// Rest distance between the magnet and the Hall chip (m).
    pub magnet_height_m: f64,
    /// Normal response: counts = gain ((h / (h - delta))^3 - 1).
    pub normal_gain_counts: f64,
    /// Shear response at rest height (counts/m of pad shear).
    pub shear_gain_counts_per_m: f64,
    /// Lateral pad bulge per unit indentation (dimensionless): indentation
    /// also shears the membrane sideways a little.
    pub bulge_per_indentation: f64,
    /// Mounting rotation of each module, `[roll, pitch, yaw]` (degrees), per
    /// finger `[thumb, index, middle]`, from the contact frame (slide, lateral,
    /// normal) to the module's (x, y, z).
    pub mount_rpy_deg: [[f64; 3]; 3],
    /// Largest off-diagonal cross-talk coefficient, drawn per module per trial.
    pub crosstalk_max: f64,
    /// Range of the per-grasp baseline of each axis `[x, y, z]`, `[lo, hi]` counts.
    pub baseline_counts: [[f64; 2]; 3],
    /// White-noise standard deviation per axis (counts).
    pub noise_std_counts: [f64; 3],
    /// Standard deviation of the slow random drift (counts).
    pub drift_std_counts: f64,
    /// Correlation time of the drift (s).
    pub drift_time_constant_s: f64,
    /// Largest linear (thermal) drift rate (counts/s), drawn per channel per trial.
    pub drift_rate_max_counts_per_s: f64,
    /// Vibration standard deviation while sliding at `vibration_ref_speed_mps` (counts).
    pub vibration_std_counts: f64,
    /// Sliding speed at which the vibration reaches its full level (m/s).
    pub vibration_ref_speed_mps: f64,
    /// Probability that a channel spikes in a sample.
    pub spike_probability: f64,
    /// Spike size range `[lo, hi]` (counts, random sign).
    pub spike_counts: [f64; 2],
    /// A patch of taxels per fingertip instead of the thesis's single module
    /// (`None`, the default).
    pub patch: Option<PatchConfig>,
    /// Fixes each module's cross-talk and gains, as a real kit's are: drawn
    /// from this seed (and the module's finger and taxel) instead of from
    /// each trial's draws (`None`, the default: redrawn every trial, and
    /// every trial's data as before). Baselines and drift stay per trial.
    /// A rig to calibrate forces on (`slidetrack calibrate tactile`) sets it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub hardware_seed: Option<u64>,
}

/// A fingertip patch of `rows x cols` taxels (like XELA's uSPa44: 4 x 4),
/// each its own module, with the contact spread over them.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PatchConfig {
    /// Rows of taxels.
    pub rows: u32,
    /// Columns of taxels.
    pub cols: u32,
    /// Distance between neighbouring taxel centres (mm).
    pub pitch_mm: f64,
    /// Standard deviation of the contact's footprint around the patch centre (mm).
    pub contact_sigma_mm: f64,
}

impl PatchConfig {
    /// Taxel centres (mm) from the patch centre, row by row.
    pub fn taxel_positions_mm(&self) -> Vec<[f64; 2]> {
        let half = |n: u32| (f64::from(n) - 1.0) / 2.0;
        (0..self.rows)
            .flat_map(|r| {
                (0..self.cols).map(move |c| {
                    [
                        (f64::from(c) - half(self.cols)) * self.pitch_mm,
                        (f64::from(r) - half(self.rows)) * self.pitch_mm,
                    ]
                })
            })
            .collect()
    }

    /// The share of the contact's field each taxel feels: a Gaussian
    /// footprint, scaled so the weights average to 1 (the mean of the patch
    /// then feels what the thesis's single module feels).
    pub fn taxel_weights(&self) -> Vec<f64> {
        let s2 = 2.0 * self.contact_sigma_mm.max(1e-6).powi(2);
        let w: Vec<f64> =
            self.taxel_positions_mm().iter().map(|[x, y]| (-(x * x + y * y) / s2).exp()).collect();
        let mean = w.iter().sum::<f64>() / w.len().max(1) as f64;
        w.iter().map(|v| v / mean).collect()
    }
}

impl Default for TactileModelConfig {
    fn default() -> Self {
        TactileModelConfig {
            magnet_height_m: 0.002,
            normal_gain_counts: 1000.0,
            shear_gain_counts_per_m: 1.6e6,
            bulge_per_indentation: 0.08,
            mount_rpy_deg: [[4.0, -6.0, 25.0], [-5.0, 3.0, -30.0], [3.0, 5.0, 20.0]],
            crosstalk_max: 0.05,
            // Ranges like those of real XELA uSkin modules at rest.
            baseline_counts: [[30000.0, 50000.0], [15000.0, 35000.0], [32000.0, 40000.0]],
            noise_std_counts: [3.0, 3.0, 4.0],
            drift_std_counts: 15.0,
            drift_time_constant_s: 20.0,
            drift_rate_max_counts_per_s: 0.4,
            vibration_std_counts: 18.0,
            vibration_ref_speed_mps: 0.01,
            spike_probability: 2e-5,
            spike_counts: [400.0, 2500.0],
            patch: None,
            hardware_seed: None,
        }
    }
}

/// The seed of module `taxel` of `finger` under a hardware seed (SplitMix64 mixing).
fn hardware_stream(seed: u64, finger: usize, taxel: usize) -> u64 {
    let mut z = seed
        .wrapping_mul(0x9E37_79B9_7F4A_7C15)
        .wrapping_add((finger as u64).wrapping_mul(0xBF58_476D_1CE4_E5B9))
        .wrapping_add((taxel as u64).wrapping_mul(0x94D0_49BB_1331_11EB));
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// What the fingertip feels, in the contact frame.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ContactDeformation {
    /// Pad indentation (m).
    pub indentation_m: f64,
    /// Pad shear along the sliding axis (m).
    pub shear_m: f64,
    /// Sliding speed of the object over the pad (m/s).
    pub slip_speed_mps: f64,
}

/// One module with its per-trial draws and its noise state.
#[derive(Clone, Debug)]
pub struct TactileModule {
    /// Contact frame -> module channels (mount rotation, cross-talk and gain jitter).
    sensor_from_contact: Matrix3<f64>,
    /// Contact frame -> module frame (the mounting rotation alone).
    module_from_contact: Rotation3<f64>,
    baseline: Vector3<f64>,
    drift: Vector3<f64>,
    drift_rate: Vector3<f64>,
    vibration: Vector3<f64>,
}

impl TactileModule {
    /// Draws module `taxel` of `finger` for one grasp: baseline, cross-talk,
    /// gain and drift rates, all from `rng`; with `cfg.hardware_seed`, the
    /// cross-talk and gains from that seed instead (the same every trial).
    pub fn draw(
        cfg: &TactileModelConfig,
        finger: usize,
        taxel: usize,
        gain_rel: f64,
        rng: &mut ChaCha8Rng,
    ) -> TactileModule {
        let [r, p, y] = cfg.mount_rpy_deg[finger].map(f64::to_radians);
        let mount = Rotation3::from_euler_angles(r, p, y);
        let mut fixed =
            cfg.hardware_seed.map(|seed| ChaCha8Rng::seed_from_u64(hardware_stream(seed, finger, taxel)));
        let hardware = match fixed.as_mut() {
            Some(h) => h,
            None => &mut *rng,
        };
        let mut crosstalk = Matrix3::identity();
        for i in 0..3 {
            for j in 0..3 {
                if i != j {
                    crosstalk[(i, j)] = hardware.random_range(-cfg.crosstalk_max..=cfg.crosstalk_max);
                }
            }
        }
        let gains = Matrix3::from_diagonal(&Vector3::from_fn(|_, _| {
            1.0 + hardware.random_range(-gain_rel..=gain_rel)
        }));
        let baseline = Vector3::from_fn(|i, _| {
            let [lo, hi] = cfg.baseline_counts[i];
            rng.random_range(lo..=hi).round()
        });
        let drift_rate = Vector3::from_fn(|_, _| {
            rng.random_range(-cfg.drift_rate_max_counts_per_s..=cfg.drift_rate_max_counts_per_s)
        });
        TactileModule {
            sensor_from_contact: gains * crosstalk * mount.matrix(),
            module_from_contact: mount,
            baseline,
            drift: Vector3::zeros(),
            drift_rate,
            vibration: Vector3::zeros(),
        }
    }

    /// The field the magnet produces at the chip, in the contact frame (counts).
    fn field(cfg: &TactileModelConfig, d: &ContactDeformation) -> Vector3<f64> {
        let h = cfg.magnet_height_m;
        let delta = d.indentation_m.clamp(0.0, 0.9 * h);
        let closeness = h / (h - delta);
        let normal = cfg.normal_gain_counts * (closeness.powi(3) - 1.0);
        // Shear sensitivity grows as the magnet nears the chip.
        let shear_gain = cfg.shear_gain_counts_per_m * closeness.powi(4);
        let lateral = cfg.bulge_per_indentation * delta;
        Vector3::new(shear_gain * d.shear_m, shear_gain * lateral, normal)
    }

    /// Raw counts of one scan taken `dt_s` after the previous one.
    pub fn sample(
        &mut self,
        cfg: &TactileModelConfig,
        d: &ContactDeformation,
        t_s: f64,
        dt_s: f64,
        rng: &mut ChaCha8Rng,
    ) -> [u16; 3] {
        self.sample_share(cfg, d, 1.0, t_s, dt_s, rng)
    }

    /// Raw counts of one scan of a taxel that feels `share` of the contact's
    /// field (1 for a single module; see [`PatchConfig::taxel_weights`]).
    pub fn sample_share(
        &mut self,
        cfg: &TactileModelConfig,
        d: &ContactDeformation,
        share: f64,
        t_s: f64,
        dt_s: f64,
        rng: &mut ChaCha8Rng,
    ) -> [u16; 3] {
        let decay = (-dt_s / cfg.drift_time_constant_s).exp();
        let drift_kick = cfg.drift_std_counts * (1.0 - decay * decay).sqrt();
        let level = (d.slip_speed_mps.abs() / cfg.vibration_ref_speed_mps).min(1.0);
        let signal = self.sensor_from_contact * (Self::field(cfg, d) * share);
        let mut out = [0u16; 3];
        for (i, o) in out.iter_mut().enumerate() {
            let n: f64 = StandardNormal.sample(rng);
            self.drift[i] = self.drift[i] * decay + drift_kick * n;
            // Vibration: coloured noise (first-order, ~half a sample of memory).
            let n: f64 = StandardNormal.sample(rng);
            self.vibration[i] = 0.5 * self.vibration[i] + 0.866 * cfg.vibration_std_counts * level * n;
            let white: f64 = StandardNormal.sample(rng);
            let mut v = self.baseline[i]
                + signal[i]
                + self.drift[i]
                + self.drift_rate[i] * t_s
                + self.vibration[i]
                + cfg.noise_std_counts[i] * white;
            if rng.random_bool(cfg.spike_probability) {
                let size = rng.random_range(cfg.spike_counts[0]..=cfg.spike_counts[1]);
                v += if rng.random_bool(0.5) { size } else { -size };
            }
            *o = v.round().clamp(0.0, u16::MAX as f64) as u16;
        }
        out
    }

    /// A force given in the contact frame (slide, lateral, normal), in the
    /// module's frame (x, y, z): the mounting rotation alone, without the
    /// chip's gains and cross-talk (N in, N out).
    pub fn force_in_module_frame(&self, force_in_contact_n: [f64; 3]) -> [f64; 3] {
        let v = self.module_from_contact * Vector3::from(force_in_contact_n);
        [v.x, v.y, v.z]
    }

    /// The module's baseline for this grasp (counts), without drift.
    pub fn baseline(&self) -> [f64; 3] {
        [self.baseline.x, self.baseline.y, self.baseline.z]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn quiet() -> TactileModelConfig {
        TactileModelConfig {
            crosstalk_max: 0.0,
            noise_std_counts: [0.0; 3],
            drift_std_counts: 0.0,
            drift_rate_max_counts_per_s: 0.0,
            vibration_std_counts: 0.0,
            spike_probability: 0.0,
            mount_rpy_deg: [[0.0; 3]; 3],
            ..TactileModelConfig::default()
        }
    }

    #[test]
    fn normal_response_is_the_inverse_cube_law() {
        let cfg = quiet();
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let mut m = TactileModule::draw(&cfg, 0, 0, 0.0, &mut rng);
        let b = m.baseline();
        let d = ContactDeformation { indentation_m: 0.0005, ..Default::default() };
        let raw = m.sample(&cfg, &d, 0.0, 0.01, &mut rng);
        let expected = 1000.0 * ((2.0f64 / 1.5).powi(3) - 1.0);
        assert!((raw[2] as f64 - b[2] - expected).abs() <= 0.5, "{raw:?} {b:?}");
    }

    #[test]
    fn mount_rotation_spreads_shear_over_x_and_y() {
        let mut cfg = quiet();
        cfg.mount_rpy_deg[1] = [0.0, 0.0, 30.0];
        cfg.bulge_per_indentation = 0.0;
        let mut rng = ChaCha8Rng::seed_from_u64(2);
        let mut m = TactileModule::draw(&cfg, 1, 0, 0.0, &mut rng);
        let b = m.baseline();
        let d = ContactDeformation { shear_m: 1e-4, ..Default::default() };
        let raw = m.sample(&cfg, &d, 0.0, 0.01, &mut rng);
        let (x, y) = (raw[0] as f64 - b[0], raw[1] as f64 - b[1]);
        let s = 1.6e6 * 1e-4;
        assert!((x - s * 30f64.to_radians().cos()).abs() <= 0.5, "{x}");
        assert!((y - s * 30f64.to_radians().sin()).abs() <= 0.5, "{y}");
    }

    #[test]
    fn a_hardware_seed_fixes_cross_talk_and_gains_but_not_the_baseline() {
        let cfg = TactileModelConfig { hardware_seed: Some(9), ..TactileModelConfig::default() };
        let draw = |trial: u64, taxel: usize| {
            TactileModule::draw(&cfg, 1, taxel, 0.08, &mut ChaCha8Rng::seed_from_u64(trial))
        };
        let (a, b) = (draw(1, 0), draw(2, 0));
        assert_eq!(a.sensor_from_contact, b.sensor_from_contact, "the same hardware in every trial");
        assert_ne!(a.baseline(), b.baseline(), "a new baseline every grasp");
        assert_ne!(a.sensor_from_contact, draw(1, 1).sensor_from_contact, "each taxel its own");
        let free = TactileModelConfig::default();
        let redrawn =
            |trial: u64| TactileModule::draw(&free, 1, 0, 0.08, &mut ChaCha8Rng::seed_from_u64(trial));
        assert_ne!(redrawn(1).sensor_from_contact, redrawn(2).sensor_from_contact, "redrawn without a seed");
    }

    #[test]
    fn counts_saturate_instead_of_wrapping() {
        let mut cfg = quiet();
        cfg.baseline_counts = [[65000.0, 65000.0]; 3];
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let mut m = TactileModule::draw(&cfg, 2, 0, 0.0, &mut rng);
        let d = ContactDeformation { indentation_m: 0.0015, ..Default::default() };
        assert_eq!(m.sample(&cfg, &d, 0.0, 0.01, &mut rng)[2], u16::MAX);
    }
}
