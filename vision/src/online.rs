//! The vision trackers online: [`OnlineTracker`] takes RGB-D frames with the
//! masks and poses that arrived by their time and returns pose and velocity
//! estimates. [`MaskUkfTracker`] and [`RoftTracker`] wrap the estimators with
//! the front-ends (point clouds, optical flow, depth rendering).

use std::sync::Arc;

use nalgebra::{Isometry3, Vector6};
use slidetrack_core::{CameraIntrinsics, RgbdFrame, TimeNs};
use slidetrack_estimators::maskukf::state as maskukf_state;
use slidetrack_estimators::maskukf::{CloudInput, MaskUkf, MaskUkfConfig, MeasurementUsed, ObjectPoints};
use slidetrack_estimators::metrics::{position_error_m, rotation_error_deg};
use slidetrack_estimators::orientation::PoseVelocity;
use slidetrack_estimators::orientation::odometry::{OdometryCovariance, odometry_covariance};
use slidetrack_estimators::roft::pose as roft_pose;
use slidetrack_estimators::roft::{Mask, PoseUse, Roft, RoftConfig, RoftInput};

use crate::VisionError;
use crate::cloud::{depth_map, masked_cloud, pinhole};
use crate::flow::{FlowConfig, OpticalFlow};
use crate::model::ObjectModel;
use crate::sources::Arrivals;

/// The trackers.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum TrackerKind {
    /// MaskUKF (thesis Chapter 4).
    MaskUkf,
    /// ROFT (thesis Chapter 5).
    Roft,
}

impl TrackerKind {
    /// The name in topics and on the command line: `maskukf` or `roft`.
    pub fn name(self) -> &'static str {
        match self {
            TrackerKind::MaskUkf => "maskukf",
            TrackerKind::Roft => "roft",
        }
    }
}

/// What a tracker did with a frame, for logs and diagnostics.
#[derive(Clone, Debug, PartialEq)]
pub enum StepNote {
    /// MaskUKF: the measurement it used and the points in the correction.
    MaskUkf {
        /// Which cloud.
        used: MeasurementUsed,
        /// Points corrected with.
        points: usize,
        /// Points rejected as outliers.
        outliers: usize,
        /// It started again at a pose measurement this frame
        /// ([`TrackerSettings::maskukf_pose_reset`]).
        restarted: bool,
    },
    /// ROFT: flow vectors in the velocity update and the fate of a pose.
    Roft {
        /// Flow vectors used.
        flow_vectors: usize,
        /// The pose measurement of this frame.
        pose: PoseUse,
    },
}

/// The estimate after a frame.
#[derive(Clone, Debug, PartialEq)]
pub struct TrackedState {
    /// The frame's time.
    pub t: TimeNs,
    /// Pose and mixed velocity, camera frame.
    pub estimate: PoseVelocity,
    /// The covariances of the pose (camera frame) and of the twist (object
    /// frame) in the layout of ROS's `nav_msgs/Odometry`, from the filter's
    /// belief (see [`slidetrack_estimators::orientation::odometry`]).
    pub covariance: OdometryCovariance,
    /// ROFT: its velocity tracker's spatial velocity `𝒱 = (v, ω)` (m/s,
    /// rad/s, camera frame; Sec. 5.3, Table 5.3); `None` for MaskUKF.
    pub flow_velocity: Option<Vector6<f64>>,
    /// What the tracker did.
    pub note: StepNote,
}

/// A vision tracker fed frame by frame.
///
/// # Contract
/// - `process` is called once per RGB-D frame, in acquisition order, with
///   the masks and poses that became available by the frame's time (see
///   [`crate::sources::MeasurementSource`]). It does not block on I/O; its
///   cost is one tracker step (a few milliseconds at 640x480).
/// - It returns `Ok(None)` until the tracker has started (MaskUKF: an
///   initial pose and a mask; ROFT: a first pose measurement) and the
///   estimate for this frame afterwards.
/// - Bad frames (sizes that differ from the intrinsics, out-of-order times)
///   are errors; the tracker's state is unchanged and later frames can
///   follow. Missing masks, empty masks or zero depth are not errors: the
///   trackers fall back as the thesis describes. Estimates are never NaN.
pub trait OnlineTracker: Send {
    /// Which tracker.
    fn kind(&self) -> TrackerKind;
    /// One frame.
    fn process(
        &mut self,
        frame: &RgbdFrame,
        arrivals: &Arrivals,
    ) -> Result<Option<TrackedState>, VisionError>;
    /// The latest estimate.
    fn estimate(&self) -> Option<PoseVelocity>;
}

/// Everything needed to build a tracker.
#[derive(Clone, Debug, Default)]
pub struct TrackerSettings {
    /// MaskUKF's parameters.
    pub maskukf: MaskUkfConfig,
    /// ROFT's parameters.
    pub roft: RoftConfig,
    /// The optical flow (ROFT).
    pub flow: FlowConfig,
    /// A known starting pose; without one the trackers start from the
    /// first pose measurement.
    pub initial_pose: Option<Isometry3<f64>>,
    /// MaskUKF: move the estimate to a pose measurement that disagrees with
    /// it by more than this (at rest, keeping the covariance). Off by default: the thesis's MaskUKF
    /// uses masks only, and a symmetric object's estimate may legitimately
    /// differ from a pose by a symmetry turn.
    pub maskukf_pose_reset: Option<PoseReset>,
}

/// How far an estimate may be from a pose measurement before the tracker
/// starts again at the measurement.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PoseReset {
    /// Distance between the object origins (m).
    pub position_m: f64,
    /// Angle between the orientations (degrees).
    pub rotation_deg: f64,
}

impl PoseReset {
    /// True when `estimate` and `measured` differ by more than this.
    pub fn exceeded(&self, estimate: &Isometry3<f64>, measured: &Isometry3<f64>) -> bool {
        position_error_m(estimate, measured) > self.position_m
            || rotation_error_deg(estimate, measured) > self.rotation_deg
    }
}

/// Builds a tracker of `kind` for `model` seen with `intrinsics`.
pub fn build_tracker(
    kind: TrackerKind,
    model: &ObjectModel,
    intrinsics: &CameraIntrinsics,
    settings: &TrackerSettings,
) -> Result<Box<dyn OnlineTracker>, VisionError> {
    Ok(match kind {
        TrackerKind::MaskUkf => Box::new(MaskUkfTracker::new(model.object_points()?, intrinsics, settings)),
        TrackerKind::Roft => Box::new(RoftTracker::new(model, intrinsics, settings)?),
    })
}

/// Checks a frame against the intrinsics.
fn check_frame(frame: &RgbdFrame, intrinsics: &CameraIntrinsics) -> Result<(), VisionError> {
    for (what, w, h) in
        [("depth", frame.depth.width, frame.depth.height), ("colour", frame.color.width, frame.color.height)]
    {
        if (w, h) != (intrinsics.width, intrinsics.height) {
            return Err(VisionError::SizeMismatch {
                what,
                width: w,
                height: h,
                expected_width: intrinsics.width,
                expected_height: intrinsics.height,
            });
        }
    }
    Ok(())
}

/// MaskUKF online: the most recent mask available is used for each frame
/// (Sec. 4.1.6); it starts at the initial pose, or at the first pose
/// measurement.
pub struct MaskUkfTracker {
    model: Arc<ObjectPoints>,
    intrinsics: CameraIntrinsics,
    config: MaskUkfConfig,
    initial_pose: Option<Isometry3<f64>>,
    pose_reset: Option<PoseReset>,
    filter: Option<MaskUkf>,
    mask: Option<Mask>,
    last_t: Option<TimeNs>,
}

impl MaskUkfTracker {
    /// A tracker with `settings.maskukf`.
    pub fn new(
        model: Arc<ObjectPoints>,
        intrinsics: &CameraIntrinsics,
        settings: &TrackerSettings,
    ) -> MaskUkfTracker {
        MaskUkfTracker {
            model,
            intrinsics: intrinsics.clone(),
            config: settings.maskukf.clone(),
            initial_pose: settings.initial_pose,
            pose_reset: settings.maskukf_pose_reset,
            filter: None,
            mask: None,
            last_t: None,
        }
    }
}

impl OnlineTracker for MaskUkfTracker {
    fn kind(&self) -> TrackerKind {
        TrackerKind::MaskUkf
    }

    fn process(
        &mut self,
        frame: &RgbdFrame,
        arrivals: &Arrivals,
    ) -> Result<Option<TrackedState>, VisionError> {
        check_frame(frame, &self.intrinsics)?;
        if let Some(last) = self.last_t.filter(|l| *l >= frame.t) {
            return Err(VisionError::BadImage {
                what: "frame",
                detail: format!("time {} ns is not after {} ns", frame.t.0, last.0),
            });
        }
        if let Some(m) = arrivals.latest_mask() {
            self.mask = Some(m.value.clone());
        }
        let dt_s = self.last_t.map_or(1.0 / 30.0, |l| (frame.t.0 - l.0) as f64 * 1e-9);
        self.last_t = Some(frame.t);
        let measured = arrivals.latest_pose().map(|p| p.value);
        let restarted = match (&self.filter, self.pose_reset, measured) {
            (Some(f), Some(reset), Some(m)) => reset.exceeded(&f.estimate().camera_from_object, &m),
            _ => false,
        };
        match (self.filter.as_mut(), measured) {
            (Some(filter), Some(pose)) if restarted => filter.move_to(&pose)?,
            (Some(_), _) => {}
            (None, _) => {
                let Some(start) = self.initial_pose.or(measured) else {
                    return Ok(None);
                };
                let at_rest = PoseVelocity::at_rest(start);
                self.filter = Some(MaskUkf::new(self.model.clone(), self.config.clone(), &at_rest)?);
            }
        }
        let cloud = match &self.mask {
            Some(mask) => Some(masked_cloud(&frame.depth, mask, &pinhole(&self.intrinsics))?),
            None => None,
        };
        let input = match &cloud {
            Some(c) => {
                CloudInput::Cloud { points_in_camera: &c.points_in_camera, mask_pixels: c.mask_pixels }
            }
            None => CloudInput::Missing,
        };
        let Some(filter) = self.filter.as_mut() else {
            return Ok(None);
        };
        let report = filter.step(dt_s, input)?;
        let belief = filter.belief();
        let covariance = odometry_covariance(&belief.mean, &belief.cov, maskukf_state::pose_velocity)?;
        Ok(Some(TrackedState {
            t: frame.t,
            estimate: filter.estimate(),
            covariance,
            flow_velocity: None,
            note: StepNote::MaskUkf {
                used: report.used,
                points: report.points,
                outliers: report.outliers,
                restarted,
            },
        }))
    }

    fn estimate(&self) -> Option<PoseVelocity> {
        self.filter.as_ref().map(MaskUkf::estimate)
    }
}

/// ROFT online: optical flow over the mask's neighbourhood, the model's
/// rendered depth for the outlier test.
pub struct RoftTracker {
    roft: Roft,
    flow: OpticalFlow,
    intrinsics: CameraIntrinsics,
    initial_pose: Option<Isometry3<f64>>,
}

impl RoftTracker {
    /// A tracker with `settings.roft` and `settings.flow`.
    pub fn new(
        model: &ObjectModel,
        intrinsics: &CameraIntrinsics,
        settings: &TrackerSettings,
    ) -> Result<RoftTracker, VisionError> {
        let mut config = settings.roft.clone();
        // Pixels off the object by more than its size are background.
        if let Some(gate) = config.velocity.depth_gate_m.as_mut() {
            *gate = gate.max(model.radius_m());
        }
        let renderer = model.depth_renderer(intrinsics);
        Ok(RoftTracker {
            roft: Roft::new(config, pinhole(intrinsics), Some(renderer))?,
            flow: OpticalFlow::new(settings.flow)?,
            intrinsics: intrinsics.clone(),
            initial_pose: settings.initial_pose,
        })
    }

    /// The mask ROFT tracks now (for display).
    pub fn mask(&self) -> Option<&Mask> {
        self.roft.mask()
    }
}

impl OnlineTracker for RoftTracker {
    fn kind(&self) -> TrackerKind {
        TrackerKind::Roft
    }

    fn process(
        &mut self,
        frame: &RgbdFrame,
        arrivals: &Arrivals,
    ) -> Result<Option<TrackedState>, VisionError> {
        check_frame(frame, &self.intrinsics)?;
        let region = self.roft.mask().and_then(Mask::bounding_box);
        let flow = match region {
            Some(r) => self.flow.next(&frame.color, Some(r))?,
            None => {
                // No mask yet: remember the frame, no flow is needed.
                self.flow.reset();
                self.flow.next(&frame.color, None).ok().flatten();
                None
            }
        };
        let pose = match (self.initial_pose.take(), arrivals.latest_pose()) {
            (Some(start), _) => Some((frame.t.0, start)),
            (None, Some(p)) => Some((p.frame_t.0, p.value)),
            (None, None) => None,
        };
        let input = RoftInput {
            t_ns: frame.t.0,
            depth: Arc::new(depth_map(&frame.depth)),
            flow: flow.map(Arc::new),
            mask: arrivals.latest_mask().map(|m| (m.frame_t.0, m.value.clone())),
            pose,
        };
        let report = self.roft.step(input)?;
        let flow_velocity = self.roft.spatial_velocity();
        let Some(belief) = self.roft.belief() else { return Ok(None) };
        Ok(Some(TrackedState {
            t: frame.t,
            estimate: roft_pose::pose_velocity(&belief.mean),
            covariance: odometry_covariance(&belief.mean, &belief.cov, roft_pose::pose_velocity)?,
            flow_velocity: Some(flow_velocity),
            note: StepNote::Roft { flow_vectors: report.flow_vectors, pose: report.pose },
        }))
    }

    fn estimate(&self) -> Option<PoseVelocity> {
        self.roft.estimate()
    }
}
