//! [`SlowNetwork`]: an imitation of a segmentation and pose-estimation
//! network that is slow (thesis Sec. 5.5.3: Mask R-CNN and DOPE at 5 fps,
//! 200 ms late). It takes a frame when it is idle, works on it for
//! `latency_s`, and delivers a mask and a pose of that frame when it is done;
//! then it takes the newest frame. The pose is the truth with noise and
//! occasional gross outliers; the mask is the true mask made imperfect as a
//! segmentation network's are ([`MaskErrors`]: grown or shrunk by a few
//! pixels, ragged at the boundary, now and then missing). Every error is
//! drawn from a seeded generator, so a run is repeatable.
//! [`SlowNetworkConfig::exact`] keeps the timing and drops every error: the
//! delayed ground truth of the "GT" rows of Table 5.6.

use nalgebra::{Isometry3, UnitQuaternion, Vector3};
use slidetrack_core::TimeNs;
use slidetrack_estimators::roft::Mask;

use super::source::{Arrivals, Delayed, FrameTruth, MeasurementSource};
use crate::VisionError;

/// How the imitated network behaves.
#[derive(Clone, Debug, PartialEq)]
pub struct SlowNetworkConfig {
    /// Time from taking a frame to delivering its result (s). The network
    /// takes the next frame as soon as it delivers, so this is also its period.
    pub latency_s: f64,
    /// Standard deviation of the position error per axis (m).
    pub position_noise_m: f64,
    /// Standard deviation of the rotation error angle (deg).
    pub rotation_noise_deg: f64,
    /// Probability that a pose is a gross outlier.
    pub outlier_probability: f64,
    /// Range of the position error of an outlier (m).
    pub outlier_position_m: [f64; 2],
    /// Range of the rotation error of an outlier (deg).
    pub outlier_rotation_deg: [f64; 2],
    /// How the delivered masks differ from the true ones.
    pub mask_errors: MaskErrors,
    /// Seed of the errors.
    pub seed: u64,
}

impl Default for SlowNetworkConfig {
    /// 5 fps and 200 ms late, 1.5 cm and 6 degrees of error, 8% outliers
    /// of 15-35 cm and 60-180 degrees, the masks of [`MaskErrors::default`].
    fn default() -> SlowNetworkConfig {
        SlowNetworkConfig {
            latency_s: 0.2,
            position_noise_m: 0.015,
            rotation_noise_deg: 6.0,
            outlier_probability: 0.08,
            outlier_position_m: [0.15, 0.35],
            outlier_rotation_deg: [60.0, 180.0],
            mask_errors: MaskErrors::default(),
            seed: 0x6e65_7477,
        }
    }
}

impl SlowNetworkConfig {
    /// The same timing without any error: true poses and true masks,
    /// `latency_s` late (ground truth delivered as the network would).
    pub fn exact(&self) -> SlowNetworkConfig {
        SlowNetworkConfig {
            position_noise_m: 0.0,
            rotation_noise_deg: 0.0,
            outlier_probability: 0.0,
            mask_errors: MaskErrors::NONE,
            ..self.clone()
        }
    }
}

/// How the imitated segmentation differs from the true mask, per result.
#[derive(Clone, Debug, PartialEq)]
pub struct MaskErrors {
    /// The mask is shrunk (eroded) or grown (dilated) by a whole number of
    /// pixels drawn uniformly from `-max_shift_px..=max_shift_px`.
    pub max_shift_px: u32,
    /// Each pixel on the boundary of the shifted mask (inside with a
    /// neighbour outside, or outside with a neighbour inside) flips with
    /// this probability: a ragged outline.
    pub boundary_flip_probability: f64,
    /// The probability that the network finds no object: no mask is
    /// delivered for that frame (the pose still is).
    pub miss_probability: f64,
}

impl MaskErrors {
    /// The true masks.
    pub const NONE: MaskErrors =
        MaskErrors { max_shift_px: 0, boundary_flip_probability: 0.0, miss_probability: 0.0 };
}

impl Default for MaskErrors {
    /// Up to 3 px too large or too small, half of the outline flipped, 5% missed.
    fn default() -> MaskErrors {
        MaskErrors { max_shift_px: 3, boundary_flip_probability: 0.5, miss_probability: 0.05 }
    }
}

/// A result on its way: its mask (`None` when the object was missed) and pose.
type InFlight = (Option<Delayed<Mask>>, Delayed<Isometry3<f64>>);

/// The imitated network.
pub struct SlowNetwork {
    config: SlowNetworkConfig,
    busy_until: Option<TimeNs>,
    in_flight: Option<InFlight>,
    rng: u64,
    delivered_outliers: usize,
}

impl SlowNetwork {
    /// A network with `config`.
    pub fn new(config: SlowNetworkConfig) -> SlowNetwork {
        let rng = config.seed;
        SlowNetwork { config, busy_until: None, in_flight: None, rng, delivered_outliers: 0 }
    }

    /// Gross outliers delivered so far.
    pub fn outliers_delivered(&self) -> usize {
        self.delivered_outliers
    }

    fn uniform(&mut self) -> f64 {
        self.rng = splitmix64(self.rng);
        ((self.rng >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }

    fn normal(&mut self) -> f64 {
        let (a, b) = (self.uniform(), self.uniform());
        (-2.0 * a.ln()).sqrt() * (std::f64::consts::TAU * b).cos()
    }

    fn unit_vector(&mut self) -> Vector3<f64> {
        let v = Vector3::new(self.normal(), self.normal(), self.normal());
        v.try_normalize(1e-9).unwrap_or_else(Vector3::x)
    }

    /// The network's mask for a frame whose true mask is `truth`: `None`
    /// when the network misses the object.
    fn segment(&mut self, truth: &Mask) -> Option<Mask> {
        let e = self.config.mask_errors.clone();
        // Draw every number whatever the outcome, so that the poses do not
        // depend on the mask settings.
        let missed = self.uniform() < e.miss_probability;
        let span = 2 * i64::from(e.max_shift_px) + 1;
        let shift = (self.uniform() * span as f64).floor() as i64 - i64::from(e.max_shift_px);
        let seed = splitmix64(self.rng ^ 0x6d61_736b);
        if missed {
            return None;
        }
        let shifted = morph(truth, shift.clamp(-64, 64) as i32);
        Some(ragged(&shifted, e.boundary_flip_probability, seed))
    }

    /// The network's pose for a frame whose true pose is `truth`.
    fn estimate(&mut self, truth: &Isometry3<f64>) -> (Isometry3<f64>, bool) {
        let c = self.config.clone();
        let mut pose = *truth;
        let outlier = self.uniform() < c.outlier_probability;
        let (dp, angle_deg) = if outlier {
            let r = c.outlier_position_m[0]
                + (c.outlier_position_m[1] - c.outlier_position_m[0]) * self.uniform();
            let a = c.outlier_rotation_deg[0]
                + (c.outlier_rotation_deg[1] - c.outlier_rotation_deg[0]) * self.uniform();
            (self.unit_vector() * r, a)
        } else {
            let dp = Vector3::new(self.normal(), self.normal(), self.normal()) * c.position_noise_m;
            (dp, self.normal() * c.rotation_noise_deg)
        };
        pose.translation.vector += dp;
        let axis = self.unit_vector();
        pose.rotation = UnitQuaternion::from_scaled_axis(axis * angle_deg.to_radians()) * pose.rotation;
        (pose, outlier)
    }
}

impl MeasurementSource for SlowNetwork {
    fn on_frame(&mut self, t: TimeNs, truth: Option<FrameTruth<'_>>) -> Result<Arrivals, VisionError> {
        let mut out = Arrivals::default();
        if let Some((mask, pose)) = self.in_flight.take_if(|(_, p)| p.arrival_t <= t) {
            out.masks.extend(mask);
            out.poses.push(pose);
        }
        let idle = self.busy_until.is_none_or(|b| b <= t);
        if let (true, Some(truth)) = (idle, truth) {
            let arrival_t = TimeNs(t.0 + (self.config.latency_s.max(0.0) * 1e9).round() as u64);
            let (pose, outlier) = self.estimate(truth.camera_from_object);
            self.delivered_outliers += usize::from(outlier);
            let mask = self.segment(truth.mask);
            let result = (
                mask.map(|value| Delayed { frame_t: t, arrival_t, value }),
                Delayed { frame_t: t, arrival_t, value: pose },
            );
            if arrival_t <= t {
                out.masks.extend(result.0);
                out.poses.push(result.1);
            } else {
                self.in_flight = Some(result);
            }
            self.busy_until = Some(arrival_t);
        }
        Ok(out)
    }
}

/// Erodes (`px > 0`) or dilates (`px < 0`) a mask with a 3x3 cross, `|px|` times.
pub(crate) fn morph(mask: &Mask, px: i32) -> Mask {
    let mut m = mask.clone();
    for _ in 0..px.unsigned_abs() {
        let mut next = Mask::empty(m.width(), m.height());
        for v in 0..m.height() {
            for u in 0..m.width() {
                let neighbours = [(u.wrapping_sub(1), v), (u + 1, v), (u, v.wrapping_sub(1)), (u, v + 1)];
                let keep = if px > 0 {
                    m.contains(u, v) && neighbours.iter().all(|(a, b)| m.contains(*a, *b))
                } else {
                    m.contains(u, v) || neighbours.iter().any(|(a, b)| m.contains(*a, *b))
                };
                if keep {
                    next.insert(u, v);
                }
            }
        }
        m = next;
    }
    m
}

/// `mask` with each pixel of its boundary flipped with probability
/// `probability` (a generator seeded with `seed`).
fn ragged(mask: &Mask, probability: f64, seed: u64) -> Mask {
    let Some(region) = mask.bounding_box().filter(|_| probability > 0.0) else {
        return mask.clone();
    };
    let region = region.grown(1, mask.width(), mask.height());
    let mut bytes = mask.to_bytes();
    let mut rng = seed;
    for v in region.v0..region.v1 {
        for u in region.u0..region.u1 {
            let inside = mask.contains(u, v);
            let neighbours = [(u.wrapping_sub(1), v), (u + 1, v), (u, v.wrapping_sub(1)), (u, v + 1)];
            let boundary = neighbours
                .iter()
                .any(|(a, b)| *a < mask.width() && *b < mask.height() && mask.contains(*a, *b) != inside);
            if boundary {
                rng = splitmix64(rng);
                if ((rng >> 11) as f64 + 0.5) / ((1u64 << 53) as f64) < probability {
                    let i = (v * mask.width() + u) as usize;
                    bytes[i] = u8::from(!inside);
                }
            }
        }
    }
    Mask::from_bytes(mask.width(), mask.height(), &bytes).unwrap_or_else(|| mask.clone())
}

fn splitmix64(state: u64) -> u64 {
    let mut z = state.wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Translation3;

    #[test]
    fn results_arrive_every_200_ms_for_the_frame_200_ms_earlier() {
        let mut net =
            SlowNetwork::new(SlowNetworkConfig { outlier_probability: 0.0, ..SlowNetworkConfig::default() });
        let mask = Mask::empty(8, 8);
        let mut arrivals = Vec::new();
        for k in 0..40u64 {
            let t = TimeNs(k * 1_000_000_000 / 30);
            let pose = Isometry3::from_parts(
                Translation3::new(k as f64 * 0.01, 0.0, 0.7),
                UnitQuaternion::identity(),
            );
            let a = net.on_frame(t, Some(FrameTruth { camera_from_object: &pose, mask: &mask })).unwrap();
            for p in a.poses {
                arrivals.push((k, p.frame_t, p.value.translation.x));
            }
        }
        let frames: Vec<u64> = arrivals.iter().map(|a| a.0).collect();
        assert_eq!(frames, vec![6, 12, 18, 24, 30, 36]);
        for (k, frame_t, x) in arrivals {
            assert_eq!(frame_t, TimeNs((k - 6) * 1_000_000_000 / 30));
            assert!((x - (k - 6) as f64 * 0.01).abs() < 0.1);
        }
    }

    #[test]
    fn outliers_show_up_at_the_configured_rate() {
        let mut net = SlowNetwork::new(SlowNetworkConfig {
            outlier_probability: 0.25,
            latency_s: 0.0,
            ..SlowNetworkConfig::default()
        });
        let mask = Mask::empty(4, 4);
        let pose = Isometry3::identity();
        let mut gross = 0;
        for k in 0..400u64 {
            let a = net
                .on_frame(TimeNs(k + 1), Some(FrameTruth { camera_from_object: &pose, mask: &mask }))
                .unwrap();
            let p = &a.poses[0].value;
            if p.translation.vector.norm() > 0.12 {
                gross += 1;
            }
        }
        assert_eq!(gross, net.outliers_delivered());
        assert!((60..140).contains(&gross), "{gross}");
    }

    /// The imitated masks differ from the truth as a network's do, the same
    /// way for the same seed; `exact` delivers the truth with the same timing.
    #[test]
    fn masks_are_shifted_ragged_and_sometimes_missing_but_repeatable() {
        let (w, h) = (120, 90);
        let mut truth_mask = Mask::empty(w, h);
        for v in 20..70 {
            for u in 30..90 {
                truth_mask.insert(u, v);
            }
        }
        let pose = Isometry3::identity();
        let run = |config: SlowNetworkConfig| {
            let mut net = SlowNetwork::new(config);
            (0..400u64)
                .map(|k| {
                    let a = net
                        .on_frame(
                            TimeNs(k + 1),
                            Some(FrameTruth { camera_from_object: &pose, mask: &truth_mask }),
                        )
                        .unwrap();
                    assert_eq!(a.poses.len(), 1, "a pose for every result");
                    a.masks.first().map(|m| m.value.clone())
                })
                .collect::<Vec<_>>()
        };
        let config = SlowNetworkConfig { latency_s: 0.0, ..SlowNetworkConfig::default() };
        let masks = run(config.clone());
        assert_eq!(masks, run(config.clone()), "seeded");
        let missed = masks.iter().filter(|m| m.is_none()).count();
        assert!((8..40).contains(&missed), "{missed} of 400 missed at 5%");
        let mut counts = std::collections::BTreeSet::new();
        for m in masks.iter().flatten() {
            assert_ne!(m, &truth_mask);
            // Shifted by at most 3 px and ragged: within the 4 px band.
            let (inner, outer) = (morph(&truth_mask, 4), morph(&truth_mask, -4));
            assert!(inner.pixels().all(|(u, v)| m.contains(u, v)));
            assert!(m.pixels().all(|(u, v)| outer.contains(u, v)));
            counts.insert(m.count() / 200);
        }
        assert!(counts.len() >= 5, "sizes vary: {counts:?}");
        let exact = run(config.exact());
        assert!(exact.iter().all(|m| m.as_ref() == Some(&truth_mask)));
    }

    #[test]
    fn erosion_and_dilation_shrink_and_grow() {
        let mut m = Mask::empty(9, 9);
        for v in 2..7 {
            for u in 2..7 {
                m.insert(u, v);
            }
        }
        assert_eq!(morph(&m, 1).count(), 9);
        assert_eq!(morph(&m, -1).count(), 25 + 4 * 5);
        assert_eq!(morph(&m, 0), m);
    }
}
