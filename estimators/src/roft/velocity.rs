//! Stage 2 of ROFT (thesis Sec. 5.3): the object's spatial velocity
//! `𝒱 = (v, ω)` (5.4) tracked from optical flow with a linear Kalman filter.
//!
//! Motion: a random walk `𝒱_t = 𝒱_{t-1} + w`, `w ~ N(0, diag(Q_v, Q_ω))` (5.6).
//! Measurement: the flow `(Δu, Δv)` of each pixel of the mask `M_{t-1}` is
//! `J_uv(d) 𝒱 + ν` with `J_uv(d) = [J_v(d) J_ω] Δt` (5.8)-(5.9). The blocks
//! are processed by the sequential Kalman filter (Algorithm 6).
//!
//! Depth: the pixel `(u, v)` of `M_{t-1}` belongs to frame `t-1`, and (3.42)
//! uses the depth of that point when its displacement starts, so `d` is read
//! from `D_{t-1}` (the thesis writes `D_t`; for fast motion near the mask's
//! border `D_t(u, v)` may already be background).
//!
//! Background gate (an addition to the thesis, on by default, see
//! [`VelocityConfig::depth_gate_m`]): a propagated mask is ragged at its
//! border and lets background pixels in. Their flow and depth belong to
//! another surface, and a few of them bias the estimate badly because the
//! flow constrains lateral translation against rotation only weakly for a
//! small object. Pixels whose depth is further than the gate from the median
//! depth of the mask are skipped.
#![expect(non_snake_case, reason = "matrices are named as in the thesis's equations (F, H, Q, R, P, K)")]

use nalgebra::{SMatrix, SVector, Vector6};

use super::image::{DepthMap, FlowField, Mask, Pinhole};
use crate::EstimatorError;
use crate::kf::{Gaussian, predict};
use crate::seq_kf::{LinearBlock, SequentialStats, correct_linear};

/// Parameters of the velocity tracker (Table 5.1, lower half).
#[derive(Clone, Debug, PartialEq)]
pub struct VelocityConfig {
    /// `𝒱_0`: `(v, ω)` in m/s and rad/s.
    pub v0: [f64; 6],
    /// `P_𝒱,0` diagonal: (m/s)² and (rad/s)².
    pub p0: [f64; 6],
    /// `Q_v`, `Q_ω` diagonal per step: (m/s)² and (rad/s)².
    pub q: [f64; 6],
    /// `σ²` of each flow component (px²).
    pub r_px2: f64,
    /// At most this many flow vectors per frame, picked with a uniform
    /// stride over the mask (not in Table 5.1; bounds the time per frame).
    pub max_flow_vectors: usize,
    /// Skip mask pixels whose depth differs from the mask's median depth by
    /// more than this (m); `None` uses every pixel as the thesis does.
    pub depth_gate_m: Option<f64>,
}

impl Default for VelocityConfig {
    fn default() -> VelocityConfig {
        VelocityConfig {
            v0: [0.0; 6],
            p0: [1e-3; 6],
            q: [1e-1; 6],
            r_px2: 1.0,
            max_flow_vectors: 1500,
            depth_gate_m: Some(0.15),
        }
    }
}

/// `J_uv(d)` of (5.9) for pixel `(u, v)` at depth `d` (m) and step `dt` (s):
/// the flow (px) produced by the spatial velocity `(v, ω)`.
#[rustfmt::skip]
pub fn flow_jacobian(k: &Pinhole, u: f64, v: f64, d: f64, dt_s: f64) -> SMatrix<f64, 2, 6> {
    let (x, y) = (u - k.cx, v - k.cy);
    let (fx, fy) = (k.fx, k.fy);
    SMatrix::<f64, 2, 6>::new(
        fx / d, 0.0,    -x / d, -x * y / fy,          (fx * fx + x * x) / fx, -y * fx / fy,
        0.0,    fy / d, -y / d, -(fy * fy + y * y) / fy, x * y / fx,           x * fy / fx,
    ) * dt_s
}

/// The velocity tracker.
#[derive(Clone, Debug)]
pub struct VelocityTracker {
    config: VelocityConfig,
    belief: Gaussian<6>,
}

impl VelocityTracker {
    /// Starts at `𝒱_0` with `P_𝒱,0`.
    pub fn new(config: VelocityConfig) -> VelocityTracker {
        let belief = Gaussian::new(
            Vector6::from(config.v0),
            SMatrix::<f64, 6, 6>::from_diagonal(&Vector6::from(config.p0)),
        );
        VelocityTracker { config, belief }
    }

    /// The current estimate `𝒱 = (v, ω)` (m/s, rad/s).
    pub fn velocity(&self) -> Vector6<f64> {
        self.belief.mean
    }

    /// The current belief.
    pub fn belief(&self) -> &Gaussian<6> {
        &self.belief
    }

    /// One frame: prediction (5.6), then the sequential correction with the
    /// flow `F_t` of the pixels of `M_{t-1}` whose depth in `D_{t-1}` is valid.
    /// Without a mask or flow the step is a prediction. The belief is kept
    /// when the correction fails numerically.
    pub fn step(
        &mut self,
        dt_s: f64,
        camera: &Pinhole,
        mask_prev: Option<&Mask>,
        depth_prev: Option<&DepthMap>,
        flow: Option<&FlowField>,
    ) -> Result<SequentialStats, EstimatorError> {
        let F = SMatrix::<f64, 6, 6>::identity();
        let Q = SMatrix::<f64, 6, 6>::from_diagonal(&Vector6::from(self.config.q));
        let predicted = predict(&self.belief, &F, &Q);
        let (Some(mask), Some(depth), Some(flow)) = (mask_prev, depth_prev, flow) else {
            self.belief = predicted;
            return Ok(SequentialStats::default());
        };
        let mut samples: Vec<(u32, u32, f64, [f32; 2])> =
            mask.pixels().filter_map(|(u, v)| Some((u, v, depth.at(u, v)?, flow.at(u, v)?))).collect();
        if let Some(gate) = self.config.depth_gate_m
            && !samples.is_empty()
        {
            let mut depths: Vec<f64> = samples.iter().map(|s| s.2).collect();
            let middle = depths.len() / 2;
            let median = *depths.select_nth_unstable_by(middle, f64::total_cmp).1;
            samples.retain(|s| (s.2 - median).abs() <= gate);
        }
        let stride = samples.len().div_ceil(self.config.max_flow_vectors.max(1)).max(1);
        let R = SMatrix::<f64, 2, 2>::identity() * self.config.r_px2;
        let blocks = samples.iter().step_by(stride).map(|&(u, v, d, [du, dv])| LinearBlock {
            z: SVector::<f64, 2>::new(f64::from(du), f64::from(dv)),
            H: flow_jacobian(camera, f64::from(u), f64::from(v), d, dt_s),
            R,
        });
        match correct_linear(&predicted, blocks) {
            Ok((posterior, stats)) => {
                self.belief = posterior;
                Ok(stats)
            }
            Err(e) => {
                self.belief = predicted;
                Err(e)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::roft::image::PixelBox;
    use nalgebra::{Point3, Vector3};

    fn camera() -> Pinhole {
        Pinhole { width: 320, height: 240, fx: 300.0, fy: 310.0, cx: 160.0, cy: 120.0 }
    }

    /// The flow model against finite differences of the projection of a
    /// rigidly moving point.
    #[test]
    fn the_flow_jacobian_matches_the_projection() {
        let k = camera();
        let p = Point3::new(0.05, -0.03, 0.6);
        let (v, w) = (Vector3::new(0.2, -0.1, 0.3), Vector3::new(0.5, -1.0, 2.0));
        let dt = 1e-5;
        let p_dot = v + w.cross(&p.coords); // (3.40)
        let (u0, v0) = k.project([p.x, p.y, p.z]).unwrap();
        let q = p + p_dot * dt;
        let (u1, v1) = k.project([q.x, q.y, q.z]).unwrap();
        let predicted = flow_jacobian(&k, u0, v0, p.z, dt) * Vector6::new(v.x, v.y, v.z, w.x, w.y, w.z);
        // First order in dt: agreement to O(dt) relative.
        assert!((predicted[0] - (u1 - u0)).abs() < 1e-4 * (u1 - u0).abs(), "{} vs {}", predicted[0], u1 - u0);
        assert!((predicted[1] - (v1 - v0)).abs() < 1e-4 * (v1 - v0).abs());
    }

    /// A planar object at 0.6 m translating at 0.2 m/s: the tracker recovers
    /// the velocity from the exact flow.
    #[test]
    fn the_velocity_of_a_translating_plane_is_recovered() {
        let k = camera();
        let dt = 1.0 / 30.0;
        let (w, h) = (k.width, k.height);
        let mut mask = Mask::empty(w, h);
        let mut depth = DepthMap::invalid(w, h);
        let velocity = Vector6::new(0.2, -0.1, 0.05, 0.0, 0.0, 0.0);
        let region = PixelBox { u0: 100, v0: 80, u1: 220, v1: 160 };
        let mut flow_px = Vec::new();
        for v in region.v0..region.v1 {
            for u in region.u0..region.u1 {
                mask.insert(u, v);
                let d = 0.6 + 0.001 * f64::from(u - 100);
                depth.depth_m[(v * w + u) as usize] = d as f32;
                let f = flow_jacobian(&k, f64::from(u), f64::from(v), d, dt) * velocity;
                flow_px.push([f[0] as f32, f[1] as f32]);
            }
        }
        let flow = FlowField { region, flow_px };
        let mut tracker = VelocityTracker::new(VelocityConfig::default());
        for _ in 0..10 {
            let stats = tracker.step(dt, &k, Some(&mask), Some(&depth), Some(&flow)).unwrap();
            assert!(stats.used > 1000);
        }
        assert!((tracker.velocity() - velocity).norm() < 0.02, "{:?}", tracker.velocity());
        // No mask: prediction only, the estimate stays.
        let before = tracker.velocity();
        tracker.step(dt, &k, None, Some(&depth), Some(&flow)).unwrap();
        assert_eq!(tracker.velocity(), before);
    }
}
