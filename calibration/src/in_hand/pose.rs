//! The object's pose in the hand at the tactile scans: the marker poses
//! moved into the hand frame and smoothed.

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use slidetrack_core::TimeNs;
use slidetrack_estimators::EstimatorError;
use slidetrack_estimators::pose_smoother::{
    PoseMeasurement, PoseSample, PoseSmootherParams, SmoothedPose, log_likelihood, smooth_poses,
};
use slidetrack_estimators::rts::MeasurementUse;
use slidetrack_session::{ArucoDetection, GroundTruthPose, Quaternion};

/// The smoothed pose of the object in the hand at the tactile scans from
/// the marker's first sighting to its last.
#[derive(Clone, Debug, PartialEq)]
pub struct PoseTrack {
    /// The camera's pose in the hand frame that was used.
    pub hand_from_camera: Isometry3<f64>,
    /// The tactile scans, from the first sighting to the last.
    pub scans: Vec<TimeNs>,
    /// The smoothed pose at each of them (hand frame).
    pub poses: Vec<SmoothedPose>,
    /// Marker poses measured.
    pub measured: usize,
    /// Marker poses the gate rejected.
    pub rejected: usize,
    /// The times of the marker poses the smoother used (accepted by the gate).
    pub used: Vec<TimeNs>,
    /// The log-likelihood of the marker poses at the parameters used.
    pub log_likelihood: f64,
}

/// The measured marker poses of `detections` in the hand frame, with their times.
pub fn hand_poses(
    detections: &[(TimeNs, ArucoDetection)],
    hand_from_camera: &Isometry3<f64>,
) -> Vec<(TimeNs, PoseMeasurement)> {
    detections
        .iter()
        .filter(|(_, d)| d.detected)
        .filter_map(|(t, d)| {
            let p = d.position_in_camera_m?;
            let q = d.orientation_in_camera?;
            let rotation = UnitQuaternion::try_new(nalgebra::Quaternion::new(q.w, q.x, q.y, q.z), 1e-9)?;
            let camera_from_object = Isometry3::from_parts(Translation3::new(p[0], p[1], p[2]), rotation);
            let hand_from_object = hand_from_camera * camera_from_object;
            let m = PoseMeasurement {
                position_m: hand_from_object.translation.vector,
                orientation: hand_from_object.rotation,
            };
            (m.position_m.iter().all(|v| v.is_finite()) && m.orientation.coords.iter().all(|v| v.is_finite()))
                .then_some((*t, m))
        })
        .collect()
}

/// The smoother's samples of `scans` and `poses` merged in time order (a
/// pose at a scan's time shares its sample), time 0 at the first.
pub struct Samples {
    /// The samples.
    pub samples: Vec<PoseSample>,
    /// For each, the index of its scan if it is one.
    pub scan_of: Vec<Option<usize>>,
    /// For each, its log time.
    pub times: Vec<TimeNs>,
}

/// Merges `scans` and `poses` into the smoother's samples ([`Samples`]).
pub fn samples(scans: &[TimeNs], poses: &[(TimeNs, PoseMeasurement)]) -> Samples {
    let (mut out, mut scan_of, mut times) = (Vec::new(), Vec::new(), Vec::new());
    let (mut i, mut j) = (0, 0);
    let t0 = match (scans.first(), poses.first()) {
        (Some(a), Some(b)) => a.0.min(b.0.0),
        (Some(a), None) => a.0,
        (None, Some(b)) => b.0.0,
        (None, None) => return Samples { samples: out, scan_of, times },
    };
    let mut last: Option<TimeNs> = None;
    while i < scans.len() || j < poses.len() {
        let t = match (scans.get(i), poses.get(j)) {
            (Some(a), Some(b)) => (*a).min(b.0),
            (Some(a), None) => *a,
            (None, Some(b)) => b.0,
            (None, None) => break,
        };
        let scan = (scans.get(i) == Some(&t)).then_some(i);
        let measurement = (poses.get(j).map(|p| p.0) == Some(t)).then(|| poses[j].1);
        i += usize::from(scan.is_some());
        j += usize::from(measurement.is_some());
        if last == Some(t) {
            // A repeated time: keep one sample (its first scan index and measurement).
            if let (Some(s), Some(k)) = (out.last_mut(), scan_of.last_mut()) {
                let s: &mut PoseSample = s;
                s.measurement = s.measurement.or(measurement);
                *k = k.or(scan);
            }
            continue;
        }
        last = Some(t);
        out.push(PoseSample { t_s: (t.0 - t0) as f64 * 1e-9, measurement });
        scan_of.push(scan);
        times.push(t);
    }
    Samples { samples: out, scan_of, times }
}

/// The pose track of a session: its tactile `scans` (all of them), its
/// marker `detections`, `hand_from_camera`. `Ok(None)` when no detection
/// carries a pose.
pub fn pose_track(
    scans: &[TimeNs],
    detections: &[(TimeNs, ArucoDetection)],
    hand_from_camera: Isometry3<f64>,
    params: &PoseSmootherParams,
) -> Result<Option<PoseTrack>, EstimatorError> {
    let poses = hand_poses(detections, &hand_from_camera);
    let (Some(first), Some(last)) = (poses.first(), poses.last()) else { return Ok(None) };
    let (from, to) = (first.0, last.0);
    let within: Vec<TimeNs> = scans.iter().copied().filter(|t| *t >= from && *t <= to).collect();
    let Samples { samples, scan_of, times } = samples(&within, &poses);
    let smoothing = smooth_poses(params, &samples)?;
    let used = times
        .iter()
        .zip(&smoothing.measurements)
        .filter(|(_, m)| matches!(m, MeasurementUse::Accepted { .. }))
        .map(|(t, _)| *t)
        .collect();
    let mut track = PoseTrack {
        hand_from_camera,
        scans: Vec::with_capacity(within.len()),
        poses: Vec::with_capacity(within.len()),
        measured: poses.len(),
        rejected: smoothing
            .measurements
            .iter()
            .filter(|m| matches!(m, MeasurementUse::Rejected { .. }))
            .count(),
        used,
        log_likelihood: log_likelihood(params, &samples),
    };
    for (k, scan) in scan_of.iter().enumerate() {
        if let (Some(i), Some(pose)) = (scan, smoothing.smoothed.get(k)) {
            track.scans.push(within[*i]);
            track.poses.push(*pose);
        }
    }
    Ok(Some(track))
}

/// The `/ground_truth/pose` message of a smoothed pose.
pub fn pose_message(p: &SmoothedPose) -> GroundTruthPose {
    let q = p.orientation;
    let v3 = |v: Vector3<f64>| [v.x, v.y, v.z];
    let std: [f64; 12] = std::array::from_fn(|i| p.covariance[(i, i)].max(0.0).sqrt());
    GroundTruthPose {
        position_in_hand_m: v3(p.position_m),
        orientation_in_hand: Quaternion { x: q.i, y: q.j, z: q.k, w: q.w },
        velocity_in_hand_m_per_s: v3(p.velocity_m_per_s),
        angular_velocity_in_hand_rad_per_s: v3(p.angular_velocity_rad_per_s),
        std,
    }
}
