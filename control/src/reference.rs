//! The grasp-strength reference and its partition among the fingers.

use serde::{Deserialize, Serialize};

/// A smooth periodic grasp strength `tau_g,des(t)` between a maximum (the
/// object does not move) and a minimum (it slides):
/// `tau(t) = max - (max - min) d(t)^k`, `d(t) = (1 - cos(2 pi t / period)) / 2`,
/// starting at the maximum. `k = 1` is a plain cosine; a larger `k` makes
/// the dips to the minimum narrower (and the holds at the maximum longer)
/// while keeping every derivative continuous.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct GraspProfile {
    /// `tau_g,max` (counts).
    pub max_counts: f64,
    /// `tau_g,min` (counts).
    pub min_counts: f64,
    /// Period (s).
    pub period_s: f64,
    /// Dip sharpness `k` (1 = cosine).
    pub sharpness: f64,
}

impl GraspProfile {
    /// The reference `t_s` seconds into the sliding cycles (counts).
    pub fn at(&self, t_s: f64) -> f64 {
        let phase = 2.0 * std::f64::consts::PI * t_s / self.period_s;
        let dip = (0.5 * (1.0 - phase.cos())).powf(self.sharpness);
        self.max_counts - (self.max_counts - self.min_counts) * dip
    }
}

/// The grasp partition (6.11): the thumb opposes the index and middle
/// fingers together, so it gets the whole grasp strength and each of them
/// half. Returns `[thumb, index, middle]` desired z (counts).
pub fn partition(grasp_counts: f64) -> [f64; 3] {
    [grasp_counts, 0.5 * grasp_counts, 0.5 * grasp_counts]
}

/// The grasp partition (6.10)-(6.11) for two opposed pads (a parallel
/// gripper): each pad bears the whole grasp strength. Returns `[thumb,
/// index, middle]` desired z (counts); a gripper's middle entry repeats its
/// index pad.
pub fn partition_two_opposed(grasp_counts: f64) -> [f64; 3] {
    [grasp_counts; 3]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn profile_spans_max_to_min_smoothly() {
        let p = GraspProfile { max_counts: 2000.0, min_counts: 800.0, period_s: 10.0, sharpness: 1.0 };
        assert_eq!(p.at(0.0), 2000.0);
        assert!((p.at(5.0) - 800.0).abs() < 1e-9);
        assert!((p.at(10.0) - 2000.0).abs() < 1e-9);
        assert!((p.at(2.5) - 1400.0).abs() < 1e-9);
        let sharp = GraspProfile { sharpness: 3.0, ..p.clone() };
        assert!((sharp.at(5.0) - 800.0).abs() < 1e-9);
        assert!((sharp.at(2.5) - (2000.0 - 1200.0 * 0.125)).abs() < 1e-9);
    }

    #[test]
    fn partition_follows_eq_6_11() {
        assert_eq!(partition(1000.0), [1000.0, 500.0, 500.0]);
        assert_eq!(partition_two_opposed(1000.0), [1000.0; 3]);
    }
}
