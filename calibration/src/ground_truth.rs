//! Ground truth of the sliding state from the ArUco marker (thesis Sec.
//! 6.2.3): marker positions along the sliding axis (0 at the first valid
//! sample), smoothed by the constant-velocity RTS smoother at the tactile
//! scan times, the camera frames being measurements at their own times.
//!
//! Pure computation on decoded messages; [`crate::label`] reads and
//! rewrites the session file.

use nalgebra::{Matrix3, Point3, Unit, Vector3};
use serde::Deserialize;
use slidetrack_core::{CameraPlacement, TimeNs};
use slidetrack_estimators::constant_velocity::{CvParams, CvSample, CvTrack};
use slidetrack_estimators::kf::Gaussian;
use slidetrack_estimators::metrics::RunningRms;
use slidetrack_estimators::rts::MeasurementUse;
use slidetrack_session::{ArucoDetection, GroundTruthMeasurement, GroundTruthSliding, SimTruth};
use thiserror::Error;

use crate::axis::SlidingAxis;

#[path = "ground_truth_measurements.rs"]
mod measurements;
#[path = "ground_truth_params.rs"]
mod params;

pub use measurements::{AxisSource, Measurements};
pub use params::{
    DEFAULT_GATE_MAHALANOBIS2, DEFAULT_Q_POSITION_M2_PER_S, DEFAULT_Q_VELOCITY_M2_PER_S3, DEFAULT_R_M2,
    default_params, gate, parameters_record, params_from_record, thesis_params,
};

/// Why the ground truth could not be built.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum GroundTruthError {
    /// No camera frame had a usable marker position.
    #[error("no marker position in any of the {frames} camera frame(s)")]
    NoDetections {
        /// Camera frames looked at.
        frames: usize,
    },
    /// No sample times (no tactile scans).
    #[error("no tactile scans to label")]
    NoScans,
    /// The rig configuration lacks what the axis needs, or is invalid.
    #[error("rig configuration: {detail}")]
    RigConfig {
        /// What is wrong.
        detail: String,
    },
    /// The axis cannot be estimated from the marker track.
    #[error("cannot estimate the sliding axis: {reason}")]
    AxisEstimate {
        /// Why not.
        reason: String,
    },
    /// The filter failed.
    #[error("smoother: {0}")]
    Estimator(#[from] slidetrack_estimators::EstimatorError),
}

/// The part of the rig configuration the axis needs (other tables ignored).
#[derive(Debug, Default, Deserialize)]
#[serde(default)]
struct RigGeometry {
    camera: CameraSection,
    geometry: GeometrySection,
}

#[derive(Debug, Default, Deserialize)]
#[serde(default)]
struct CameraSection {
    placement: CameraPlacement,
}

#[derive(Debug, Deserialize)]
#[serde(default)]
struct GeometrySection {
    sliding_axis_in_hand: [f64; 3],
}

impl Default for GeometrySection {
    fn default() -> Self {
        GeometrySection { sliding_axis_in_hand: [0.0, 0.0, -1.0] }
    }
}

/// The sliding axis of a rig configuration (TOML, as stored in the
/// session's `rig_config`): camera placement and axis, defaults for what it omits.
pub fn axis_from_rig_config(rig_config: &str) -> Result<SlidingAxis, GroundTruthError> {
    let rig: RigGeometry = toml::from_str(rig_config)
        .map_err(|e| GroundTruthError::RigConfig { detail: e.message().to_string() })?;
    let hand_from_camera = rig
        .camera
        .placement
        .hand_from_camera()
        .map_err(|e| GroundTruthError::RigConfig { detail: e.to_string() })?;
    SlidingAxis::new(hand_from_camera, rig.geometry.sliding_axis_in_hand.into())
        .map_err(|e| GroundTruthError::RigConfig { detail: e.to_string() })
}

/// The marker positions along the sliding axis from the recorded detections.
/// `rig_config` (TOML) is needed by [`AxisSource::Config`] and, when given,
/// orients the estimated axis.
pub fn marker_positions(
    detections: &[(TimeNs, ArucoDetection)],
    source: AxisSource,
    rig_config: Option<&str>,
) -> Result<Measurements, GroundTruthError> {
    let frames = detections.len();
    let in_camera = || {
        detections.iter().filter_map(|(t, d)| {
            let p = d.position_in_camera_m?;
            p.iter().all(|v| v.is_finite()).then_some((*t, Point3::from(p)))
        })
    };
    let (raw, axis_in_camera, description): (Vec<(TimeNs, f64)>, _, String) = match source {
        AxisSource::Recorded => (
            detections
                .iter()
                .filter_map(|(t, d)| d.position_on_axis_m.filter(|p| p.is_finite()).map(|p| (*t, p)))
                .collect(),
            None,
            "position_on_axis_m of /aruco/detections, as recorded".into(),
        ),
        AxisSource::Config => {
            let text = rig_config.ok_or_else(|| GroundTruthError::RigConfig {
                detail: "the session has no rig_config metadata".into(),
            })?;
            let axis = axis_from_rig_config(text)?;
            let direction = axis.hand_from_camera.rotation.inverse() * axis.axis_in_hand.into_inner();
            (
                in_camera().map(|(t, p)| (t, axis.along_axis_m(&p))).collect(),
                Some(direction),
                "position_in_camera_m of /aruco/detections projected on the rig config's sliding axis".into(),
            )
        }
        AxisSource::Estimate => {
            let points: Vec<(TimeNs, Point3<f64>)> = in_camera().collect();
            let hint = rig_config
                .and_then(|t| axis_from_rig_config(t).ok())
                .map(|axis| axis.hand_from_camera.rotation.inverse() * axis.axis_in_hand.into_inner());
            let direction = estimate_axis(&points.iter().map(|(_, p)| *p).collect::<Vec<_>>(), hint)?;
            (
                points.iter().map(|(t, p)| (*t, direction.dot(&p.coords))).collect(),
                Some(direction.into_inner()),
                "position_in_camera_m of /aruco/detections projected on the principal direction of the marker track"
                    .into(),
            )
        }
    };
    measurements_from(raw, frames, axis_in_camera, description)
}

/// The marker positions along `axis` (its camera placement and direction in
/// the hand frame, e.g. from a hand calibration and the hand's geometry):
/// `position_in_camera_m` moved into the hand frame and projected on the
/// axis; `description` says where the axis came from.
pub fn marker_positions_on_axis(
    detections: &[(TimeNs, ArucoDetection)],
    axis: &SlidingAxis,
    description: String,
) -> Result<Measurements, GroundTruthError> {
    let raw = detections
        .iter()
        .filter_map(|(t, d)| {
            let p = d.position_in_camera_m?;
            p.iter().all(|v| v.is_finite()).then(|| (*t, axis.along_axis_m(&Point3::from(p))))
        })
        .collect();
    let direction = axis.hand_from_camera.rotation.inverse() * axis.axis_in_hand.into_inner();
    measurements_from(raw, detections.len(), Some(direction), description)
}

/// The measurements of `raw` positions along an axis: 0 at the first, times
/// strictly increasing (a repeated time keeps its first position).
fn measurements_from(
    raw: Vec<(TimeNs, f64)>,
    frames: usize,
    axis_in_camera: Option<Vector3<f64>>,
    description: String,
) -> Result<Measurements, GroundTruthError> {
    let Some(&(_, origin)) = raw.first() else { return Err(GroundTruthError::NoDetections { frames }) };
    let mut positions: Vec<(TimeNs, f64)> = Vec::with_capacity(raw.len());
    for (t, p) in raw {
        if positions.last().is_none_or(|(last, _)| t > *last) {
            positions.push((t, p - origin));
        }
    }
    let missing = frames - positions.len();
    Ok(Measurements { positions, missing, frames, axis_in_camera, source: description })
}

/// The principal direction of `points` (the eigenvector of their covariance
/// with the largest eigenvalue), oriented along `hint` when given, else so
/// that the last point is ahead of the first.
pub fn estimate_axis(
    points: &[Point3<f64>],
    hint: Option<Vector3<f64>>,
) -> Result<Unit<Vector3<f64>>, GroundTruthError> {
    if points.len() < 3 {
        let reason = format!("{} marker position(s), at least 3 needed", points.len());
        return Err(GroundTruthError::AxisEstimate { reason });
    }
    let n = points.len() as f64;
    let mean = points.iter().fold(Vector3::zeros(), |s, p| s + p.coords) / n;
    let cov = points.iter().fold(Matrix3::zeros(), |s, p| {
        let d = p.coords - mean;
        s + d * d.transpose()
    }) / n;
    let eigen = cov.symmetric_eigen();
    let (k, &largest) = eigen
        .eigenvalues
        .iter()
        .enumerate()
        .max_by(|a, b| a.1.total_cmp(b.1))
        .ok_or_else(|| GroundTruthError::AxisEstimate { reason: "no eigenvalues".into() })?;
    let spread_m = largest.max(0.0).sqrt();
    if spread_m.is_nan() || spread_m <= 1e-4 {
        let reason = format!("the marker moved only {:.2} mm (RMS) along any direction", spread_m * 1e3);
        return Err(GroundTruthError::AxisEstimate { reason });
    }
    let mut direction: Vector3<f64> = eigen.eigenvectors.column(k).into_owned();
    let forward = match hint {
        Some(h) => h,
        None => points[points.len() - 1].coords - points[0].coords,
    };
    if direction.dot(&forward) < 0.0 {
        direction = -direction;
    }
    Ok(Unit::new_normalize(direction))
}

/// One time of the filter's grid.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GridPoint {
    /// The time.
    pub t: TimeNs,
    /// A tactile scan is at this time (the ground truth is output here).
    pub scan: bool,
    /// Index into the measurements, when a marker position is at this time.
    pub measurement: Option<usize>,
}

/// The filter and smoother run over the merged time grid.
#[derive(Clone, Debug, PartialEq)]
pub struct GroundTruth {
    /// The grid: scan times and measurement times, merged.
    pub grid: Vec<GridPoint>,
    /// The filter's and the smoother's results at every grid point.
    pub track: CvTrack,
    /// The measurements used, as given.
    pub positions: Vec<(TimeNs, f64)>,
}

/// Runs the filter and the smoother over the scan times `scans` and the
/// marker positions `positions` (both increasing in time).
pub fn smooth_ground_truth(
    scans: &[TimeNs],
    positions: &[(TimeNs, f64)],
    params: &CvParams,
) -> Result<GroundTruth, GroundTruthError> {
    if scans.is_empty() {
        return Err(GroundTruthError::NoScans);
    }
    let grid = merge_times(scans, positions);
    let t0 = grid[0].t;
    let samples: Vec<CvSample> = grid
        .iter()
        .map(|g| CvSample {
            // Exact integer nanoseconds from the first sample, then seconds.
            t_s: (g.t.0 - t0.0) as f64 * 1e-9,
            z_m: g.measurement.map(|k| positions[k].1),
        })
        .collect();
    let track = params.smooth(&samples)?;
    Ok(GroundTruth { grid, track, positions: positions.to_vec() })
}

/// Scan and measurement times in order; a measurement at a scan's time shares its point.
fn merge_times(scans: &[TimeNs], positions: &[(TimeNs, f64)]) -> Vec<GridPoint> {
    let mut grid: Vec<GridPoint> = Vec::with_capacity(scans.len() + positions.len());
    let (mut i, mut j) = (0, 0);
    while i < scans.len() || j < positions.len() {
        let scan_t = scans.get(i).copied();
        let meas_t = positions.get(j).map(|p| p.0);
        let t = match (scan_t, meas_t) {
            (Some(a), Some(b)) => a.min(b),
            (Some(a), None) => a,
            (None, Some(b)) => b,
            (None, None) => break,
        };
        let scan = scan_t == Some(t);
        let measurement = (meas_t == Some(t)).then_some(j);
        i += usize::from(scan);
        j += usize::from(measurement.is_some());
        match grid.last_mut() {
            // A repeated scan time: one grid point.
            Some(last) if last.t == t => {
                last.scan |= scan;
                last.measurement = last.measurement.or(measurement);
            }
            _ => grid.push(GridPoint { t, scan, measurement }),
        }
    }
    grid
}

impl GroundTruth {
    /// The smoothed state at every scan time (eq. 6.15).
    pub fn sliding(&self) -> Vec<(TimeNs, GroundTruthSliding)> {
        self.at_scans(&self.track.smoothed)
    }

    /// The causal Kalman filter's state at every scan time (for comparison).
    pub fn filtered(&self) -> Vec<(TimeNs, GroundTruthSliding)> {
        self.at_scans(&self.track.filtered)
    }

    fn at_scans(&self, beliefs: &[Gaussian<2>]) -> Vec<(TimeNs, GroundTruthSliding)> {
        self.grid
            .iter()
            .zip(beliefs)
            .filter(|(g, _)| g.scan)
            .map(|(g, b)| {
                let c = b.cov;
                let message = GroundTruthSliding {
                    position: b.mean[0],
                    velocity: b.mean[1],
                    covariance: [[c[(0, 0)], c[(0, 1)]], [c[(1, 0)], c[(1, 1)]]],
                };
                (g.t, message)
            })
            .collect()
    }

    /// Every marker position with what the filter did with it.
    pub fn measurements(&self) -> Vec<(TimeNs, GroundTruthMeasurement)> {
        self.grid
            .iter()
            .zip(&self.track.measurements)
            .filter_map(|(g, used)| {
                let k = g.measurement?;
                let (rejected, mahalanobis2) = match *used {
                    MeasurementUse::Accepted { mahalanobis2 } => (false, mahalanobis2),
                    MeasurementUse::Rejected { mahalanobis2 } => (true, mahalanobis2),
                    MeasurementUse::Missing => return None,
                };
                Some((g.t, GroundTruthMeasurement { position: self.positions[k].1, rejected, mahalanobis2 }))
            })
            .collect()
    }

    /// Measurements the gate rejected.
    pub fn rejected(&self) -> usize {
        self.track.measurements.iter().filter(|m| matches!(m, MeasurementUse::Rejected { .. })).count()
    }
}

/// Root-mean-square errors of the ground truth against the simulator's truth.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rmse {
    /// Position (m).
    pub position_m: f64,
    /// Velocity (m/s).
    pub velocity_mps: f64,
    /// Samples compared.
    pub samples: usize,
}

/// RMSE of `estimate` against `truth` over the scans from `measured_from`
/// (the first marker measurement) to `measured_until` (the last one, or the
/// release of the hand if earlier: outside that span the ground truth is
/// extrapolated, and after the release the object falls out of the hand).
/// The truth's position is shifted to 0 at the first measurement, as the
/// marker's is; times are matched exactly, else the truth is interpolated.
pub fn rmse_against_truth(
    estimate: &[(TimeNs, GroundTruthSliding)],
    truth: &[(TimeNs, SimTruth)],
    measured_from: TimeNs,
    measured_until: TimeNs,
) -> Option<Rmse> {
    let at = |t: TimeNs| -> Option<(f64, f64)> {
        // Before the first truth sample the object has not moved yet.
        let first = truth.first()?;
        if t <= first.0 {
            return Some((first.1.position, first.1.velocity));
        }
        let k = truth.partition_point(|(tt, _)| *tt < t);
        let after = truth.get(k)?;
        if after.0 == t {
            return Some((after.1.position, after.1.velocity));
        }
        let before = truth.get(k.checked_sub(1)?)?;
        let w = (t.0 - before.0.0) as f64 / (after.0.0 - before.0.0) as f64;
        let lerp = |a: f64, b: f64| a + w * (b - a);
        Some((lerp(before.1.position, after.1.position), lerp(before.1.velocity, after.1.velocity)))
    };
    let (origin, _) = at(measured_from)?;
    let (mut position, mut velocity) = (RunningRms::default(), RunningRms::default());
    for (t, e) in estimate.iter().filter(|(t, _)| (measured_from..=measured_until).contains(t)) {
        let Some((p, v)) = at(*t) else { continue };
        position.add(e.position - (p - origin));
        velocity.add(e.velocity - v);
    }
    Some(Rmse { position_m: position.rms()?, velocity_mps: velocity.rms()?, samples: position.count() })
}

#[cfg(test)]
#[path = "ground_truth_tests.rs"]
mod tests;
