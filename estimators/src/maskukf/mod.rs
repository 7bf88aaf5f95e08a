//! MaskUKF (thesis Chapter 4): 6D object pose and velocity tracking from the
//! partial point cloud of a segmented object, with a sequential UKF.
//!
//! Per frame (the algorithm table of Sec. 4.1.7):
//! 1. if the mask is missing or empty, or the ratio of valid depth pixels is
//!    below `ε^valid`, the measurement is a *virtual* point cloud sampled on
//!    the model at the previous estimate (Sec. 4.1.6), which drives the
//!    velocities to zero while information is missing;
//! 2. otherwise outliers are removed (Sec. 4.1.5, [`reject_outliers`]) once
//!    the filter is in the steady state that test assumes (median distance of
//!    the points from the object at the previous estimate at most
//!    `δ^outlier`; until then every point is kept);
//! 3. prediction with the WNA model (4.5)-(4.7) and sequential UKF correction
//!    (Algorithm 7 with the Euler-angle operators of Algorithm 8) with the
//!    likelihood-field measurement (4.8)-(4.11) ([`measurement`]).
//!
//! Inputs are point clouds in the camera frame; building them from depth and
//! masks is the caller's job (the `vision` crate). Defaults are Table 4.1.
//! The filter never holds NaN: a step that fails numerically keeps the
//! prediction (or the previous belief) and says so in the [`StepReport`].

pub mod measurement;
mod model;
pub mod outliers;
pub mod state;

use nalgebra::{DMatrix, DVector, Isometry3, Point3};
use thiserror::Error;

pub use model::{ModelError, ObjectPoints};
pub use outliers::reject_outliers;

use crate::EstimatorError;
use crate::orientation::{Composite, PoseVelocity};
use crate::seq_ukf::{BlockNoise, StatisticalJacobians, correct_sequential};
use crate::ukf::{Belief, UtParams, predict_additive};

/// Parameters of MaskUKF; the defaults are Table 4.1 of the thesis plus the
/// implementation settings documented on each field.
#[derive(Clone, Debug, PartialEq)]
pub struct MaskUkfConfig {
    /// `P_0` diagonal entries for `p` (m²), `v` ((m/s)²), `o` (rad²), `ȯ` ((rad/s)²).
    pub p0: [f64; 4],
    /// Power spectral density `Q_p` of the linear acceleration, (m/s)²/s.
    pub q_p: [f64; 3],
    /// Power spectral density `Q_o` of the Euler-angle acceleration, (rad/s)²/s.
    pub q_o: [f64; 3],
    /// `σ²` of each point coordinate in `R_t` (m²).
    pub r_m2: f64,
    /// `δ^outlier` (m).
    pub outlier_threshold_m: f64,
    /// `ε^valid`: below this ratio of valid depth pixels in the mask the
    /// virtual point cloud is used.
    pub valid_ratio_min: f64,
    /// Outlier rejection on (the thesis's method; off for ablations).
    pub outlier_rejection: bool,
    /// At most this many measured points are used per frame, picked with a
    /// uniform stride (not in Table 4.1; bounds the time per frame).
    pub max_points: usize,
    /// Points in the virtual cloud (not in Table 4.1).
    pub virtual_points: usize,
    /// Fewer points than this after outlier rejection count as a missing
    /// measurement (not in Table 4.1).
    pub min_points: usize,
    /// Unscented transform parameters.
    pub ut: UtParams,
    /// Seed of the virtual-cloud sampling.
    pub seed: u64,
}

impl Default for MaskUkfConfig {
    fn default() -> MaskUkfConfig {
        MaskUkfConfig {
            p0: [1e-2; 4],
            q_p: [0.1; 3],
            q_o: [0.2; 3],
            r_m2: 1e-3,
            outlier_threshold_m: 0.01,
            valid_ratio_min: 0.2,
            outlier_rejection: true,
            max_points: 400,
            virtual_points: 400,
            min_points: 10,
            ut: UtParams::default(),
            seed: 0x6d61_736b,
        }
    }
}

/// Errors of a MaskUKF step; the filter keeps its belief.
#[derive(Clone, Debug, Error, PartialEq)]
#[non_exhaustive]
pub enum MaskUkfError {
    /// `dt` is not a positive finite number of seconds.
    #[error("time step {dt_s} s is not positive and finite")]
    BadTimeStep {
        /// The step given (s).
        dt_s: f64,
    },
    /// The initial pose or velocity is not finite.
    #[error("the initial pose or velocity is not finite")]
    BadInitialState,
    /// The filter math failed (also in the prediction): the belief is unchanged.
    #[error("MaskUKF step failed: {0}")]
    Filter(#[from] EstimatorError),
}

/// The measurement of one frame.
#[derive(Clone, Copy, Debug)]
pub enum CloudInput<'a> {
    /// No mask for this frame (or an empty one).
    Missing,
    /// The points with valid depth inside the mask (camera frame, m) and the
    /// number of mask pixels `L_t` (valid or not).
    Cloud {
        /// The points `z_j`.
        points_in_camera: &'a [Point3<f64>],
        /// `L_t`.
        mask_pixels: usize,
    },
}

/// Which measurement a step used.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MeasurementUsed {
    /// The measured cloud.
    Measured,
    /// The virtual cloud, because the mask was missing or empty.
    VirtualNoMask,
    /// The virtual cloud, because too few pixels had valid depth.
    VirtualLowValidRatio,
    /// The virtual cloud, because too few points survived outlier rejection.
    VirtualTooFewPoints,
    /// Prediction only: the correction failed numerically.
    PredictionOnly,
}

/// What one step did.
#[derive(Clone, Debug, PartialEq)]
pub struct StepReport {
    /// Which measurement was used.
    pub used: MeasurementUsed,
    /// Points in the correction.
    pub points: usize,
    /// Points removed as outliers.
    pub outliers: usize,
    /// Why the correction was skipped, for [`MeasurementUsed::PredictionOnly`].
    pub failure: Option<EstimatorError>,
}

/// The MaskUKF tracker of one object.
pub struct MaskUkf {
    config: MaskUkfConfig,
    model: std::sync::Arc<ObjectPoints>,
    belief: Belief<Composite>,
    rng: u64,
}

impl MaskUkf {
    /// A tracker starting at `initial` (pose and velocity, camera frame) with
    /// covariance `P_0` from `config`.
    pub fn new(
        model: std::sync::Arc<ObjectPoints>,
        config: MaskUkfConfig,
        initial: &PoseVelocity,
    ) -> Result<MaskUkf, MaskUkfError> {
        if !initial.is_finite() {
            return Err(MaskUkfError::BadInitialState);
        }
        let mean = state::state_from_pose(initial);
        let p0: Vec<f64> = config.p0.iter().flat_map(|v| [*v; 3]).collect();
        let belief = Belief::new(mean, DMatrix::from_diagonal(&DVector::from_vec(p0)))?;
        let rng = config.seed;
        Ok(MaskUkf { config, model, belief, rng })
    }

    /// Moves the estimate to `camera_from_object`, at rest, keeping the
    /// covariance: the filter's confidence stays what it had learnt, so the
    /// next correction does not swing as from `P_0` (not in the thesis; a
    /// restart at an external pose measurement).
    pub fn move_to(&mut self, camera_from_object: &Isometry3<f64>) -> Result<(), MaskUkfError> {
        let target = PoseVelocity::at_rest(*camera_from_object);
        if !target.is_finite() {
            return Err(MaskUkfError::BadInitialState);
        }
        self.belief.mean = state::state_from_pose(&target);
        Ok(())
    }

    /// The current estimate.
    pub fn estimate(&self) -> PoseVelocity {
        state::pose_velocity(&self.belief.mean)
    }

    /// The current belief (state (4.1), covariance 12 x 12).
    pub fn belief(&self) -> &Belief<Composite> {
        &self.belief
    }

    /// The configuration.
    pub fn config(&self) -> &MaskUkfConfig {
        &self.config
    }

    /// One frame, `dt_s` after the previous one.
    pub fn step(&mut self, dt_s: f64, input: CloudInput<'_>) -> Result<StepReport, MaskUkfError> {
        if !(dt_s > 0.0 && dt_s.is_finite()) {
            return Err(MaskUkfError::BadTimeStep { dt_s });
        }
        let previous = state::camera_from_object(&self.belief.mean);
        let (points, used, outliers) = self.select_points(input, &previous);
        let f_matrix = state::F(dt_s);
        let q_matrix = state::Q(&self.config.q_p, &self.config.q_o, dt_s);
        let predicted =
            predict_additive(&self.belief, &q_matrix, |x| state::motion(x, &f_matrix), &self.config.ut)?;
        match self.correct(&predicted, &points) {
            Ok(posterior) => {
                self.belief = posterior;
                Ok(StepReport { used, points: points.len(), outliers, failure: None })
            }
            Err(e) => {
                self.belief = predicted;
                Ok(StepReport {
                    used: MeasurementUsed::PredictionOnly,
                    points: 0,
                    outliers,
                    failure: Some(e),
                })
            }
        }
    }

    /// Steps 1-2: the measured cloud (subsampled, outliers removed) or the
    /// virtual cloud, and why.
    fn select_points(
        &mut self,
        input: CloudInput<'_>,
        previous: &Isometry3<f64>,
    ) -> (Vec<Point3<f64>>, MeasurementUsed, usize) {
        let c = &self.config;
        let measured = match input {
            CloudInput::Missing => None,
            // An empty mask; a mask without valid depth is the low-ratio case.
            CloudInput::Cloud { points_in_camera: [], mask_pixels: 0 } => None,
            CloudInput::Cloud { points_in_camera, mask_pixels } => Some((points_in_camera, mask_pixels)),
        };
        let Some((all, mask_pixels)) = measured else {
            return (self.virtual_cloud(previous), MeasurementUsed::VirtualNoMask, 0);
        };
        let finite: Vec<Point3<f64>> =
            all.iter().filter(|p| p.iter().all(|v| v.is_finite())).copied().collect();
        let valid_ratio = finite.len() as f64 / mask_pixels.max(finite.len()).max(1) as f64;
        if valid_ratio < c.valid_ratio_min {
            return (self.virtual_cloud(previous), MeasurementUsed::VirtualLowValidRatio, 0);
        }
        let stride = finite.len().div_ceil(c.max_points.max(1));
        let points: Vec<Point3<f64>> = finite.into_iter().step_by(stride.max(1)).collect();
        let (points, outliers) = if c.outlier_rejection {
            let projections = measurement::project(&points, previous, &self.model);
            if steady(&points, &projections, c.outlier_threshold_m) {
                let kept = reject_outliers(&points, &projections, c.outlier_threshold_m);
                let outliers = points.len() - kept.len();
                (kept.into_iter().map(|i| points[i]).collect(), outliers)
            } else {
                (points, 0)
            }
        } else {
            (points, 0)
        };
        if points.len() < c.min_points {
            return (self.virtual_cloud(previous), MeasurementUsed::VirtualTooFewPoints, outliers);
        }
        (points, MeasurementUsed::Measured, outliers)
    }

    /// `z^virtual(x_{t-1})`: model points drawn at random (a new draw each
    /// frame), placed at the previous estimate.
    fn virtual_cloud(&mut self, previous: &Isometry3<f64>) -> Vec<Point3<f64>> {
        let model = self.model.points();
        (0..self.config.virtual_points.max(1))
            .map(|_| {
                self.rng = splitmix64(self.rng);
                previous * model[(self.rng % model.len() as u64) as usize]
            })
            .collect()
    }

    /// Step 3: the sequential UKF correction with the likelihood field.
    fn correct(
        &self,
        predicted: &Belief<Composite>,
        points: &[Point3<f64>],
    ) -> Result<Belief<Composite>, EstimatorError> {
        if points.is_empty() {
            return Ok(predicted.clone());
        }
        let jacobians = StatisticalJacobians::new(predicted, &self.config.ut, |sigma| {
            measurement::predicted_clouds(sigma, points, &self.model)
        })?;
        let z = DVector::from_iterator(3 * points.len(), points.iter().flat_map(|p| [p.x, p.y, p.z]));
        let variances = vec![self.config.r_m2; points.len()];
        let noise = BlockNoise::Isotropic { block_size: 3, variances: &variances };
        correct_sequential(predicted, &jacobians, &z, noise)
    }
}

/// The steady-state condition the outlier test of Sec. 4.1.5 assumes: the
/// cloud fits the object at the previous estimate, which is taken to hold
/// when the median distance of the points from their projections is at most
/// `δ^outlier`. While the filter is still converging (for example from a
/// perturbed start) the pair test would reject valid points on the side the
/// estimate is off, and is skipped.
fn steady(points: &[Point3<f64>], projections: &[Point3<f64>], threshold_m: f64) -> bool {
    let mut residuals: Vec<f64> = points.iter().zip(projections).map(|(z, pi)| (z - pi).norm()).collect();
    if residuals.is_empty() {
        return false;
    }
    let middle = residuals.len() / 2;
    let median = *residuals.select_nth_unstable_by(middle, f64::total_cmp).1;
    median <= threshold_m
}

/// SplitMix64: a small, good, seedable generator for the virtual cloud.
pub(crate) fn splitmix64(state: u64) -> u64 {
    let mut z = state.wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

#[cfg(test)]
mod tests;
