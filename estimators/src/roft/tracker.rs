//! [`Roft`]: the three stages, their buffers and the synchronisation of
//! delayed pose measurements (the algorithm table of Sec. 5.4.7).

#![expect(non_snake_case, reason = "matrices are named as in the thesis's equations (F, H, Q, R, P, K)")]

use std::collections::VecDeque;
use std::sync::Arc;

use nalgebra::{DMatrix, DVector, Isometry3, Vector6};

use super::config::{DepthRenderer, RoftConfig};
use super::error::RoftError;
use super::image::{DepthMap, Mask, Pinhole, SharedFlow};
use super::mask::{DelayedMaskUse, MaskSync};
use super::pose::{self, MeasuredParts};
use super::velocity::VelocityTracker;
use crate::EstimatorError;
use crate::orientation::{Composite, PoseVelocity};
use crate::ukf::{Belief, correct, predict};

/// The inputs of one RGB-D frame.
#[derive(Clone, Debug)]
pub struct RoftInput {
    /// Acquisition time of the frame (ns); identifies the frame for delayed
    /// measurements.
    pub t_ns: u64,
    /// The depth `D_t` (m).
    pub depth: Arc<DepthMap>,
    /// The flow `F_t` from the previous frame to this one (`None` on the first
    /// frame or when it could not be computed).
    pub flow: Option<SharedFlow>,
    /// A mask `M^d` that arrived now, with the time of the frame it was
    /// computed on.
    pub mask: Option<(u64, Mask)>,
    /// A pose `T^d` (`camera_from_object`) that arrived now, with the time of
    /// the frame it was computed on.
    pub pose: Option<(u64, Isometry3<f64>)>,
}

/// What happened to a pose measurement.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PoseUse {
    /// No pose this frame.
    None,
    /// The tracker started from it.
    Initialised,
    /// Fused at its frame, then this many frames were replayed.
    Fused {
        /// Frames replayed after the pose's frame.
        replayed: usize,
    },
    /// Rejected by the depth test (5.20): the rendering errors with and
    /// without the pose (m, summed over the mask).
    Outlier {
        /// `e^{𝒱,T}`.
        error_with_pose_m: f64,
        /// `e^{𝒱}`.
        error_without_pose_m: f64,
    },
    /// Ignored (pose measurements are switched off).
    Ignored,
    /// Older than the history: dropped.
    TooOld,
    /// Not finite: dropped.
    Invalid,
}

/// What one step did.
#[derive(Clone, Debug, PartialEq)]
pub struct RoftReport {
    /// The delayed mask.
    pub mask: DelayedMaskUse,
    /// Flow vectors used by the velocity tracker.
    pub flow_vectors: usize,
    /// The pose measurement.
    pub pose: PoseUse,
    /// A numerical failure that made a filter skip a correction.
    pub failure: Option<EstimatorError>,
}

/// One frame of history.
#[derive(Clone, Debug)]
struct FrameRecord {
    t_ns: u64,
    /// Time since the previous frame (s), 0 for the first.
    dt_s: f64,
    /// `𝒱_j` when the velocity tracker measured flow at this frame.
    velocity: Option<Vector6<f64>>,
    /// Pixels of `M_j` with their measured depth `D_j` (m), subsampled.
    observed: Vec<(u32, u32, f32)>,
    /// The filtering belief of the pose UKF after this frame.
    filtered: Option<Belief<Composite>>,
}

/// The ROFT tracker of one object.
pub struct Roft {
    config: RoftConfig,
    camera: Pinhole,
    masks: MaskSync,
    velocity: VelocityTracker,
    renderer: Option<Box<dyn DepthRenderer>>,
    history: VecDeque<FrameRecord>,
    depth_prev: Option<Arc<DepthMap>>,
}

impl Roft {
    /// A tracker for a camera; `renderer` renders the object's depth for the
    /// outlier test (without one the test is off).
    pub fn new(
        config: RoftConfig,
        camera: Pinhole,
        renderer: Option<Box<dyn DepthRenderer>>,
    ) -> Result<Roft, RoftError> {
        if !camera.is_valid() {
            return Err(RoftError::BadIntrinsics(camera));
        }
        Ok(Roft {
            masks: MaskSync::new(config.history_frames, config.mask_sync),
            velocity: VelocityTracker::new(config.velocity.clone()),
            config,
            camera,
            renderer,
            history: VecDeque::new(),
            depth_prev: None,
        })
    }

    /// The current mask `M_t` (the region the next flow is needed on).
    pub fn mask(&self) -> Option<&Mask> {
        self.masks.mask()
    }

    /// The current spatial velocity `𝒱 = (v, ω)` of the velocity tracker.
    pub fn spatial_velocity(&self) -> Vector6<f64> {
        self.velocity.velocity()
    }

    /// The current estimate, once a pose measurement has started the tracker.
    pub fn estimate(&self) -> Option<PoseVelocity> {
        self.belief().map(|b| pose::pose_velocity(&b.mean))
    }

    /// The pose UKF's current belief (state (5.10), 12 x 12 covariance in
    /// the tangent of its `⊕`), once a pose measurement has started the tracker.
    pub fn belief(&self) -> Option<&Belief<Composite>> {
        self.history.back()?.filtered.as_ref()
    }

    /// The configuration.
    pub fn config(&self) -> &RoftConfig {
        &self.config
    }

    /// One frame (the loop body of the algorithm table, Sec. 5.4.7).
    #[expect(
        clippy::too_many_lines,
        reason = "one function on purpose: it reads as the algorithm table of Sec. 5.4.7, line by line"
    )]
    pub fn step(&mut self, input: RoftInput) -> Result<RoftReport, RoftError> {
        let RoftInput { t_ns, depth, flow, mask, pose } = input;
        let previous = self.history.back().map(|r| r.t_ns);
        if let Some(previous_ns) = previous.filter(|p| *p >= t_ns) {
            return Err(RoftError::OutOfOrder { previous_ns, t_ns });
        }
        if (depth.width, depth.height) != (self.camera.width, self.camera.height) {
            return Err(RoftError::DepthSize {
                width: depth.width,
                height: depth.height,
                expected_width: self.camera.width,
                expected_height: self.camera.height,
            });
        }
        let dt_s = previous.map_or(0.0, |p| (t_ns - p) as f64 * 1e-9);
        let mut report =
            RoftReport { mask: DelayedMaskUse::None, flow_vectors: 0, pose: PoseUse::None, failure: None };

        // Stage 1: M_t from M_{t-1} and F_t, or from a delayed mask (5.2)-(5.3).
        let mask_prev = self.masks.mask().cloned();
        report.mask = self.masks.on_frame(t_ns, flow.clone(), mask);

        // Stage 2: 𝒱_t from the flow of M_{t-1} (5.6)-(5.9).
        let mut velocity = None;
        if previous.is_some() {
            match self.velocity.step(
                dt_s,
                &self.camera,
                mask_prev.as_ref(),
                self.depth_prev.as_deref(),
                flow.as_deref(),
            ) {
                Ok(stats) => {
                    report.flow_vectors = stats.used;
                    velocity = (stats.used > 0).then(|| self.velocity.velocity());
                }
                Err(e) => report.failure = Some(e),
            }
        }
        let observed = self.observed_pixels(&depth);
        self.history.push_back(FrameRecord { t_ns, dt_s, velocity, observed, filtered: None });
        while self.history.len() > self.config.history_frames.max(2) {
            self.history.pop_front();
        }
        self.depth_prev = Some(depth);

        // Stage 3: the pose UKF.
        let last = self.history.len() - 1;
        let pose = pose.filter(|(_, p)| {
            let ok = p.to_homogeneous().iter().all(|v| v.is_finite());
            if !ok {
                report.pose = PoseUse::Invalid;
            }
            ok
        });
        let initialised = self.history.iter().any(|r| r.filtered.is_some());
        match pose {
            Some((k_ns, camera_from_object)) if !initialised => {
                let i = if self.config.pose_sync { self.index_of(k_ns).unwrap_or(last) } else { last };
                self.initialise(i, &camera_from_object);
                report.pose = PoseUse::Initialised;
                self.replay(i + 1, &mut report);
            }
            Some(_) if !self.config.use_pose => {
                report.pose = PoseUse::Ignored;
                self.replay(last, &mut report);
            }
            Some((k_ns, camera_from_object)) => {
                let i = if self.config.pose_sync { self.index_of(k_ns) } else { Some(last) };
                match i {
                    Some(i) if i > 0 && self.history[i - 1].filtered.is_some() => {
                        report.pose = self.fuse_pose(i, &camera_from_object, &mut report);
                        let replayed = last - i;
                        self.replay(i + 1, &mut report);
                        if report.pose == (PoseUse::Fused { replayed: 0 }) {
                            report.pose = PoseUse::Fused { replayed };
                        }
                    }
                    _ => {
                        report.pose = PoseUse::TooOld;
                        self.replay(last, &mut report);
                    }
                }
            }
            None => {
                if initialised {
                    self.replay(last, &mut report);
                }
            }
        }
        Ok(report)
    }

    /// The index of the frame recorded at `t_ns`, or of the latest frame
    /// before it; `None` when older than the history.
    fn index_of(&self, t_ns: u64) -> Option<usize> {
        if self.history.front().is_none_or(|r| r.t_ns > t_ns) {
            return None;
        }
        self.history.iter().rposition(|r| r.t_ns <= t_ns)
    }

    /// Pixels of `M_t` with valid depth in `D_t`, subsampled, for (5.19).
    fn observed_pixels(&self, depth: &DepthMap) -> Vec<(u32, u32, f32)> {
        let Some(mask) = self.masks.mask() else {
            return Vec::new();
        };
        let all: Vec<(u32, u32, f32)> =
            mask.pixels().filter_map(|(u, v)| depth.at(u, v).map(|d| (u, v, d as f32))).collect();
        let stride = all.len().div_ceil(self.config.max_outlier_pixels.max(1)).max(1);
        all.into_iter().step_by(stride).collect()
    }

    /// Starts the pose UKF at frame `i` from a pose, at rest, with `P_0`.
    fn initialise(&mut self, i: usize, camera_from_object: &Isometry3<f64>) {
        let mean = pose::state_from_pose(&PoseVelocity::at_rest(*camera_from_object));
        let p0: Vec<f64> = self.config.p0.iter().flat_map(|v| [*v; 3]).collect();
        let cov = DMatrix::from_diagonal(&DVector::from_vec(p0));
        for r in self.history.iter_mut() {
            r.filtered = None;
        }
        self.history[i].filtered = Some(Belief { mean, cov });
    }

    /// The prediction from frame `i - 1` to frame `i`.
    fn predict_to(&self, i: usize) -> Result<Belief<Composite>, EstimatorError> {
        let prior =
            self.history[i - 1].filtered.as_ref().ok_or(EstimatorError::NonFiniteState { what: "prior" })?;
        let dt_s = self.history[i].dt_s;
        let Q = pose::process_noise(&self.config.q_p, &self.config.q_omega, dt_s);
        predict(prior, &Q, |x, w| pose::motion(x, w, dt_s), &self.config.ut)
    }

    /// The correction of `predicted` with `parts` of the measurement.
    fn correct_with(
        &self,
        predicted: &Belief<Composite>,
        parts: MeasuredParts,
        camera_from_object: Option<&Isometry3<f64>>,
        velocity: Option<&Vector6<f64>>,
    ) -> Result<Belief<Composite>, EstimatorError> {
        let z = pose::measurement(parts, camera_from_object, velocity)
            .ok_or(EstimatorError::NonFiniteMeasurement)?;
        let R = pose::measurement_noise(parts, &self.config.r);
        Ok(correct(predicted, &z, &R, |x, nu| pose::measure(parts, x, nu), &self.config.ut)?.posterior)
    }

    /// Frames `from..` again: prediction and correction with the buffered
    /// velocities (Sec. 5.4.5), storing each filtering belief.
    fn replay(&mut self, from: usize, report: &mut RoftReport) {
        for i in from.max(1)..self.history.len() {
            let Ok(predicted) = self.predict_to(i) else {
                // The prior is missing or the prediction failed: keep the
                // previous belief (never NaN).
                self.history[i].filtered = self.history[i - 1].filtered.clone();
                continue;
            };
            let velocity = self.history[i].velocity.filter(|_| self.config.use_velocity);
            let filtered = match velocity {
                Some(v) => self
                    .correct_with(&predicted, MeasuredParts::Velocity, None, Some(&v))
                    .unwrap_or_else(|e| {
                        report.failure = Some(e);
                        predicted
                    }),
                None => predicted,
            };
            self.history[i].filtered = Some(filtered);
        }
    }

    /// Frame `i` with the pose `T^d`: two hypotheses, with and without the
    /// pose (5.4.6); the depth test (5.19)-(5.20) picks one.
    fn fuse_pose(
        &mut self,
        i: usize,
        camera_from_object: &Isometry3<f64>,
        report: &mut RoftReport,
    ) -> PoseUse {
        let Ok(predicted) = self.predict_to(i) else {
            return PoseUse::TooOld;
        };
        let velocity = self.history[i].velocity.filter(|_| self.config.use_velocity);
        let with_pose_parts =
            if velocity.is_some() { MeasuredParts::PoseAndVelocity } else { MeasuredParts::Pose };
        let without_pose = match velocity {
            Some(v) => self.correct_with(&predicted, MeasuredParts::Velocity, None, Some(&v)),
            None => Ok(predicted.clone()),
        }
        .unwrap_or_else(|e| {
            report.failure = Some(e);
            predicted.clone()
        });
        let with_pose =
            match self.correct_with(&predicted, with_pose_parts, Some(camera_from_object), velocity.as_ref())
            {
                Ok(b) => b,
                Err(e) => {
                    report.failure = Some(e);
                    self.history[i].filtered = Some(without_pose);
                    return PoseUse::Invalid;
                }
            };
        if self.config.outlier_rejection
            && let Some((e_pose, e_velocity)) = self.depth_errors(i, &with_pose, &without_pose)
            && e_pose > self.config.gamma * e_velocity
        {
            self.history[i].filtered = Some(without_pose);
            return PoseUse::Outlier { error_with_pose_m: e_pose, error_without_pose_m: e_velocity };
        }
        self.history[i].filtered = Some(with_pose);
        PoseUse::Fused { replayed: 0 }
    }

    /// `e(D)` of (5.19) for both hypotheses, `None` without a renderer or
    /// observed pixels.
    fn depth_errors(
        &mut self,
        i: usize,
        with_pose: &Belief<Composite>,
        without_pose: &Belief<Composite>,
    ) -> Option<(f64, f64)> {
        let observed = &self.history[i].observed;
        if observed.is_empty() {
            return None;
        }
        let renderer = self.renderer.as_mut()?;
        let pixels: Vec<(u32, u32)> = observed.iter().map(|(u, v, _)| (*u, *v)).collect();
        let mut error = |belief: &Belief<Composite>| {
            let pose = pose::pose_velocity(&belief.mean).camera_from_object;
            let mut rendered = Vec::with_capacity(pixels.len());
            renderer.render(&pose, &pixels, &mut rendered);
            observed.iter().zip(&rendered).map(|((_, _, d), r)| f64::from((d - r).abs())).sum::<f64>()
        };
        Some((error(with_pose), error(without_pose)))
    }
}
