//! Evaluation of the trackers against ground truth: running a tracker over
//! an input, the metrics of Sec. 3.4 over the tracked frames, and the ROFT
//! variants of Table 5.6 on any RGB-D source with truth.

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3, Vector6};
use serde::Serialize;
use slidetrack_core::ObjectTruth;
use slidetrack_estimators::maskukf::ObjectPoints;
use slidetrack_estimators::metrics::{
    FrameErrors, FrameEvaluation, SequenceMetrics, frame_errors, summarize,
};
use slidetrack_estimators::orientation::PoseVelocity;
use slidetrack_estimators::roft::RoftConfig;

use crate::VisionError;
use crate::input::{RgbdSample, RgbdSource};
use crate::model::ObjectModel;
use crate::online::{OnlineTracker, TrackedState, TrackerKind, TrackerSettings, build_tracker};
use crate::sources::{Combined, FrameTruth, MeasurementSource, SlowNetwork, SlowNetworkConfig};

/// One evaluated frame.
#[derive(Clone, Debug, PartialEq)]
pub struct TrackedFrame {
    /// The truth.
    pub truth: ObjectTruth,
    /// The tracker's estimate, once started.
    pub estimate: Option<PoseVelocity>,
    /// The newest pose measurement received by this frame (the "network
    /// alone" baseline: the last available output, thesis Sec. 5.5.5).
    pub last_measured_pose: Option<Isometry3<f64>>,
    /// ROFT's velocity-tracker estimate `𝒱 = (v, ω)` (m/s, rad/s).
    pub flow_velocity: Option<Vector6<f64>>,
}

impl TrackedFrame {
    /// The true spatial velocity `𝒱 = (ṗ + ω × (-p), ω)` (3.26) of the frame.
    pub fn true_flow_velocity(&self) -> Vector6<f64> {
        let p = self.truth.camera_from_object.translation.vector;
        let w = self.truth.angular_velocity_radps;
        let v = self.truth.linear_velocity_mps + w.cross(&(-p));
        Vector6::new(v.x, v.y, v.z, w.x, w.y, w.z)
    }
}

/// Runs `tracker` (or no tracker, for the measurement baseline) over
/// `source`, with `measurements`; `on_frame` sees every frame and estimate.
/// Frames without truth are tracked but not returned.
pub fn track(
    source: &mut dyn RgbdSource,
    measurements: &mut dyn MeasurementSource,
    mut tracker: Option<&mut (dyn OnlineTracker + '_)>,
    mut on_frame: impl FnMut(&RgbdSample, Option<&TrackedState>),
) -> Result<Vec<TrackedFrame>, VisionError> {
    let mut out = Vec::new();
    let mut last_measured_pose = None;
    while let Some(sample) = source.next_frame()? {
        let truth = match (&sample.truth, &sample.truth_mask) {
            (Some(t), Some(m)) => Some(FrameTruth { camera_from_object: &t.camera_from_object, mask: m }),
            _ => None,
        };
        let arrivals = measurements.on_rgbd_frame(&sample.frame, truth)?;
        if let Some(p) = arrivals.latest_pose() {
            last_measured_pose = Some(p.value);
        }
        let state = match tracker.as_deref_mut() {
            Some(t) => t.process(&sample.frame, &arrivals)?,
            None => None,
        };
        on_frame(&sample, state.as_ref());
        if let Some(truth) = sample.truth {
            out.push(TrackedFrame {
                truth,
                flow_velocity: state.as_ref().and_then(|s| s.flow_velocity),
                estimate: state.map(|s| s.estimate),
                last_measured_pose,
            });
        }
    }
    Ok(out)
}

/// Which estimate of a [`TrackedFrame`] is scored.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Scored {
    /// The tracker's estimate.
    Tracker,
    /// The last pose measurement (no velocity).
    Measurement,
}

/// The metrics of `frames` from frame `skip` on (frames before the inputs
/// could start any tracker are left out). A frame without an estimate scores
/// as a pose 10 m away (beyond every threshold) at rest.
pub fn score(frames: &[TrackedFrame], skip: usize, scored: Scored, model: &ObjectPoints) -> SequenceMetrics {
    summarize(&errors(frames, skip, scored, model))
}

/// The per-frame errors behind [`score`].
pub fn errors(
    frames: &[TrackedFrame],
    skip: usize,
    scored: Scored,
    model: &ObjectPoints,
) -> Vec<FrameErrors> {
    let far = |truth: &Isometry3<f64>| {
        Isometry3::from_parts(
            Translation3::from(truth.translation.vector + Vector3::new(10.0, 0.0, 0.0)),
            UnitQuaternion::identity(),
        )
    };
    let evaluations: Vec<FrameEvaluation> = frames
        .iter()
        .skip(skip)
        .map(|f| {
            let truth = f.truth.camera_from_object;
            let (estimate, velocity) = match scored {
                Scored::Tracker => match &f.estimate {
                    Some(e) => {
                        (e.camera_from_object, Some((e.linear_velocity_mps, e.angular_velocity_radps)))
                    }
                    None => (far(&truth), Some((Vector3::zeros(), Vector3::zeros()))),
                },
                Scored::Measurement => (f.last_measured_pose.unwrap_or_else(|| far(&truth)), None),
            };
            let flow_velocity = match scored {
                Scored::Tracker => f.flow_velocity.map(|e| (e, f.true_flow_velocity())),
                Scored::Measurement => None,
            };
            FrameEvaluation {
                estimate,
                truth,
                linear_velocity_mps: velocity.map(|(v, _)| (v, f.truth.linear_velocity_mps)),
                angular_velocity_radps: velocity.map(|(_, w)| (w, f.truth.angular_velocity_radps)),
                flow_velocity,
            }
        })
        .collect();
    evaluations.iter().map(|e| frame_errors(e, model)).collect()
}

/// The rows of Table 5.6 (and the MaskUKF check on the same sequences).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum Variant {
    /// ROFT with ground-truth masks and poses (at the network's rate and delay).
    RoftGtSegmPose,
    /// ROFT with ground-truth poses (at the network's rate and delay).
    RoftGtPose,
    /// ROFT with ground-truth masks (at the network's rate and delay).
    RoftGtSegm,
    /// ROFT.
    Roft,
    /// ROFT fusing delayed poses at the current frame.
    RoftWithoutPoseSync,
    /// ROFT without the depth test of poses.
    RoftWithoutOutlierRejection,
    /// ROFT with delayed masks used as they arrive.
    RoftWithoutSegmSync,
    /// ROFT without velocities in the pose UKF.
    RoftWithoutVelocity,
    /// ROFT without pose measurements after the first.
    RoftWithoutPose,
    /// The network at 30 fps without delay ("DOPE (ideal)").
    NetworkIdeal,
    /// The network at 5 fps, 200 ms late: its last pose ("DOPE").
    Network,
}

impl Variant {
    /// The rows of Table 5.6, in its order.
    pub const TABLE_5_6: [Variant; 11] = [
        Variant::RoftGtSegmPose,
        Variant::RoftGtPose,
        Variant::RoftGtSegm,
        Variant::Roft,
        Variant::RoftWithoutPoseSync,
        Variant::RoftWithoutOutlierRejection,
        Variant::RoftWithoutSegmSync,
        Variant::RoftWithoutVelocity,
        Variant::RoftWithoutPose,
        Variant::NetworkIdeal,
        Variant::Network,
    ];

    /// The row's label.
    pub fn label(self) -> &'static str {
        match self {
            Variant::RoftGtSegmPose => "ROFT w/ GT segm. and pose",
            Variant::RoftGtPose => "ROFT w/ GT pose",
            Variant::RoftGtSegm => "ROFT w/ GT segm.",
            Variant::Roft => "ROFT",
            Variant::RoftWithoutPoseSync => "ROFT w/o pose sync.",
            Variant::RoftWithoutOutlierRejection => "ROFT w/o outlier rej.",
            Variant::RoftWithoutSegmSync => "ROFT w/o segm. sync.",
            Variant::RoftWithoutVelocity => "ROFT w/o velocity",
            Variant::RoftWithoutPose => "ROFT w/o pose",
            Variant::NetworkIdeal => "network (ideal)",
            Variant::Network => "network",
        }
    }

    fn roft_config(self, base: &RoftConfig) -> RoftConfig {
        let mut c = base.clone();
        match self {
            Variant::RoftWithoutPoseSync => c.pose_sync = false,
            Variant::RoftWithoutOutlierRejection => c.outlier_rejection = false,
            Variant::RoftWithoutSegmSync => c.mask_sync = false,
            Variant::RoftWithoutVelocity => c.use_velocity = false,
            Variant::RoftWithoutPose => c.use_pose = false,
            _ => {}
        }
        c
    }

    /// Where the masks and poses come from. Ground truth ("GT") arrives as
    /// the network's results do (same rate and delay, without their
    /// errors); only the network's "ideal" row has results for every frame
    /// without delay.
    pub fn measurements(self, network: &SlowNetworkConfig) -> Box<dyn MeasurementSource> {
        let slow = || Box::new(SlowNetwork::new(network.clone()));
        let slow_truth = || Box::new(SlowNetwork::new(network.exact()));
        match self {
            Variant::RoftGtSegmPose => slow_truth(),
            Variant::RoftGtPose => Box::new(Combined { masks: slow(), poses: slow_truth() }),
            Variant::RoftGtSegm => Box::new(Combined { masks: slow_truth(), poses: slow() }),
            Variant::NetworkIdeal => {
                Box::new(SlowNetwork::new(SlowNetworkConfig { latency_s: 0.0, ..network.clone() }))
            }
            _ => slow(),
        }
    }
}

/// The result of one variant over a set of sequences.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct VariantResult {
    /// The variant.
    pub variant: Variant,
    /// Its label.
    pub label: &'static str,
    /// Metrics over the frames of every sequence together.
    pub metrics: SequenceMetrics,
}

/// The per-frame errors of `variant` on one sequence: `source` gives its
/// frames with their truth, `model` is the object it shows. The first `skip`
/// frames are left out (no variant has an estimate before the network's first
/// result). `network` should be seeded per sequence.
pub fn variant_errors(
    variant: Variant,
    source: &mut dyn RgbdSource,
    model: &ObjectModel,
    skip: usize,
    network: &SlowNetworkConfig,
    settings: &TrackerSettings,
) -> Result<Vec<FrameErrors>, VisionError> {
    let intrinsics = source.intrinsics().clone();
    let mut measurements = variant.measurements(network);
    let run = match variant {
        Variant::Network | Variant::NetworkIdeal => track(source, measurements.as_mut(), None, |_, _| {})?,
        _ => {
            let s = TrackerSettings { roft: variant.roft_config(&settings.roft), ..settings.clone() };
            let mut tracker = build_tracker(TrackerKind::Roft, model, &intrinsics, &s)?;
            track(source, measurements.as_mut(), Some(tracker.as_mut()), |_, _| {})?
        }
    };
    let scored = match variant {
        Variant::Network | Variant::NetworkIdeal => Scored::Measurement,
        _ => Scored::Tracker,
    };
    Ok(errors(&run, skip, scored, &*model.object_points()?))
}
