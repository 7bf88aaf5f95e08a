//! [`InHandVision`]: a vision tracker running online on the simulated
//! in-hand rig, beside the dEKF (`slidetrack track --vision maskukf|roft`).
//!
//! It owns everything between the rig's truth and an estimate: the RGB-D
//! rendering of the in-hand scene ([`InHandRgbd`], camera placed like the
//! rig's camera), the source of masks and poses (by default the imitated
//! slow network, 5 fps and 200 ms late), the tracker, and optionally the
//! session channels it writes. Per camera frame the caller hands over the
//! frame's time and the simulator's travel and velocity along the sliding
//! axis; it gets back the estimate in the camera frame and, for comparison
//! with the dEKF, the estimated travel and velocity along the sliding axis.
//!
//! ```no_run
//! use slidetrack_core::TimeNs;
//! use slidetrack_sim::ObjectConfig;
//! use slidetrack_sim::camera::SimCameraConfig;
//! use slidetrack_vision::TrackerKind;
//! use slidetrack_experiment::vision_inhand::{InHandVision, InHandVisionConfig};
//! # fn run(logger: slidetrack_session::Logger) -> Result<(), Box<dyn std::error::Error>> {
//! let object = ObjectConfig::load("box")?;
//! let config = InHandVisionConfig::new(TrackerKind::Roft, 7);
//! let mut vision = InHandVision::new(
//!     &config,
//!     &SimCameraConfig::default(),
//!     &object.geometry,
//!     [0.10, 0.0, 0.0],  // object_start_in_hand_m
//!     [0.0, 0.0, -1.0],  // sliding_axis_in_hand
//! )?
//! .with_recording(logger, false)?; // /estimate/{pose,transform,velocity}/roft
//! // For each camera frame: its time and sequence number, and the simulator's
//! // truth (SimTruth::position_m, SimTruth::velocity_mps) at that time.
//! let step = vision.on_frame(TimeNs(33_333_333), 1, 0.002, 0.01)?;
//! if let Some(p) = step.position_m {
//!     println!("ROFT: {:.2} cm along the sliding axis", p * 100.0);
//! }
//! # Ok(()) }
//! ```

use nalgebra::{Isometry3, Translation3, Unit, UnitQuaternion, Vector3};
use slidetrack_core::TimeNs;
use slidetrack_session::Logger;
use slidetrack_sim::ObjectGeometry;
use slidetrack_sim::camera::SimCameraConfig;
use slidetrack_sim::rgbd::InHandRgbd;
use slidetrack_vision::VisionError;
use slidetrack_vision::cloud::mask;
use slidetrack_vision::input::encode_color_jpeg;
use slidetrack_vision::model::ObjectModel;
use slidetrack_vision::online::{OnlineTracker, TrackedState, TrackerKind, TrackerSettings, build_tracker};
use slidetrack_vision::record::{EstimateChannels, RgbdChannels};
use slidetrack_vision::sources::{
    FrameTruth, MeasurementSource, SlowNetwork, SlowNetworkConfig, TruthSource,
};

use crate::vision_sim::VisionSimError;

/// JPEG quality of recorded colour frames (1-100).
const JPEG_QUALITY: i32 = 90;

/// Where the in-hand tracker's masks and poses come from.
#[derive(Clone, Debug, PartialEq)]
pub enum InHandMeasurements {
    /// The imitated slow network: true masks and noisy poses (with gross
    /// outliers), computed on one frame and delivered `latency_s` later.
    Network(SlowNetworkConfig),
    /// The true mask and pose of every frame, without delay.
    Truth,
}

/// How to run a tracker on the in-hand rig.
#[derive(Clone, Debug)]
pub struct InHandVisionConfig {
    /// MaskUKF or ROFT.
    pub kind: TrackerKind,
    /// Masks and poses.
    pub measurements: InHandMeasurements,
    /// The trackers' parameters (Tables 4.1 and 5.1 by default).
    /// `settings.initial_pose` is ignored: see `start_at_truth`.
    pub settings: TrackerSettings,
    /// Start the tracker at the object's true pose of the first frame (the
    /// rig's known starting position); otherwise it waits for the first
    /// pose measurement (about 200 ms with the default network).
    pub start_at_truth: bool,
    /// Seed of the rendering noise (and of the network's errors, mixed in).
    pub seed: u64,
}

impl InHandVisionConfig {
    /// `kind` with the default network (5 fps, 200 ms late, 1.5 cm and 6 deg
    /// of pose noise, 8% outliers), the thesis's parameters, started at the
    /// true first pose.
    pub fn new(kind: TrackerKind, seed: u64) -> InHandVisionConfig {
        InHandVisionConfig {
            kind,
            measurements: InHandMeasurements::Network(SlowNetworkConfig {
                seed: SlowNetworkConfig::default().seed ^ seed,
                ..SlowNetworkConfig::default()
            }),
            settings: TrackerSettings::default(),
            start_at_truth: true,
            seed,
        }
    }
}

/// What the tracker made of one camera frame.
#[derive(Clone, Debug, PartialEq)]
pub struct InHandStep {
    /// The frame's time.
    pub t: TimeNs,
    /// The estimate in the camera frame, once the tracker has started.
    pub state: Option<TrackedState>,
    /// The estimated `hand_from_object` (m).
    pub hand_from_object: Option<Isometry3<f64>>,
    /// Estimated travel along the sliding axis from the object's starting
    /// position (m); the same quantity as `SimTruth::position_m` and the
    /// dEKF's `p` (eq. 6.1).
    pub position_m: Option<f64>,
    /// Estimated velocity along the sliding axis (m/s), like `SimTruth::velocity_mps`.
    pub velocity_mps: Option<f64>,
    /// Pose measurements that arrived with this frame.
    pub poses_arrived: usize,
}

/// The channels an [`InHandVision`] writes.
struct Recording {
    logger: Logger,
    estimates: EstimateChannels,
    rgbd: Option<RgbdChannels>,
}

/// A vision tracker on the simulated in-hand rig. See the module docs.
pub struct InHandVision {
    kind: TrackerKind,
    scene: InHandRgbd,
    tracker: Box<dyn OnlineTracker>,
    measurements: Box<dyn MeasurementSource>,
    start_at_truth: bool,
    settings: TrackerSettings,
    model: ObjectModel,
    object_start_in_hand: Vector3<f64>,
    sliding_axis_in_hand: Unit<Vector3<f64>>,
    recording: Option<Recording>,
    started: bool,
}

impl InHandVision {
    /// A tracker for the box of `geometry` (the in-hand scene of
    /// [`InHandRgbd`]) seen by the rig's `camera`, the object starting at
    /// `object_start_in_hand_m` (m, hand frame) and sliding along
    /// `sliding_axis_in_hand` (unit vector, hand frame): the values of the
    /// rig configuration's `[geometry]`.
    pub fn new(
        config: &InHandVisionConfig,
        camera: &SimCameraConfig,
        geometry: &ObjectGeometry,
        object_start_in_hand_m: [f64; 3],
        sliding_axis_in_hand: [f64; 3],
    ) -> Result<InHandVision, VisionSimError> {
        let axis = Vector3::from(sliding_axis_in_hand);
        let bad_axis = || VisionError::BadValue {
            what: "sliding axis",
            detail: format!("{sliding_axis_in_hand:?} is not a usable direction"),
        };
        if !axis.iter().all(|v| v.is_finite()) {
            return Err(bad_axis().into());
        }
        let sliding_axis_in_hand = Unit::try_new(axis, 1e-9).ok_or_else(bad_axis)?;
        let start = Vector3::from(object_start_in_hand_m);
        if !start.iter().all(|v| v.is_finite()) {
            return Err(VisionError::BadValue {
                what: "object start",
                detail: format!("{object_start_in_hand_m:?} m is not finite"),
            }
            .into());
        }
        let scene = InHandRgbd::new(camera, geometry, config.seed)?;
        let model = ObjectModel::from_mesh("in-hand box", scene.mesh().clone());
        let intrinsics = scene.intrinsics().clone();
        let settings = TrackerSettings { initial_pose: None, ..config.settings.clone() };
        // Built now so that a bad model or configuration fails here, not mid-trial.
        let tracker = build_tracker(config.kind, &model, &intrinsics, &settings)?;
        let measurements: Box<dyn MeasurementSource> = match &config.measurements {
            InHandMeasurements::Network(n) => Box::new(SlowNetwork::new(n.clone())),
            InHandMeasurements::Truth => Box::new(TruthSource { masks: true, poses: true }),
        };
        Ok(InHandVision {
            kind: config.kind,
            scene,
            tracker,
            measurements,
            start_at_truth: config.start_at_truth,
            settings,
            model,
            object_start_in_hand: start,
            sliding_axis_in_hand,
            recording: None,
            started: false,
        })
    }

    /// Also writes every estimate to `logger` on `/estimate/pose/<tracker>`,
    /// `/estimate/transform/<tracker>` and `/estimate/velocity/<tracker>`;
    /// with `rgbd`, also the rendered frames and what the network delivered
    /// (`/rgbd/color`, `/rgbd/depth`, `/rgbd/mask`, `/rgbd/calibration`,
    /// `/sim/object`, `/vision/mask`, `/vision/pose`; about 1 MB per frame).
    /// Channels are registered here.
    pub fn with_recording(mut self, logger: Logger, rgbd: bool) -> Result<InHandVision, VisionError> {
        let estimates = EstimateChannels::register(&logger, self.kind)?;
        let rgbd = if rgbd { Some(RgbdChannels::register(&logger, self.scene.intrinsics())?) } else { None };
        self.recording = Some(Recording { logger, estimates, rgbd });
        Ok(self)
    }

    /// Which tracker.
    pub fn kind(&self) -> TrackerKind {
        self.kind
    }

    /// The camera pose in the hand frame.
    pub fn hand_from_camera(&self) -> &Isometry3<f64> {
        self.scene.hand_from_camera()
    }

    /// One camera frame at `t` (session time, increasing) with sequence
    /// number `sequence`, the object having slid `travel_m` (m) along the
    /// sliding axis at `velocity_mps` (m/s): the simulator's truth at the
    /// frame. Renders the frame, polls the measurement source, steps the
    /// tracker and records. Costs one rendering plus one tracker step
    /// (milliseconds at 640x480).
    ///
    /// Errors: a time that does not increase, non-finite truth, or a
    /// failed session write. The tracker's state is unchanged on error.
    pub fn on_frame(
        &mut self,
        t: TimeNs,
        sequence: u64,
        travel_m: f64,
        velocity_mps: f64,
    ) -> Result<InHandStep, VisionError> {
        if !(travel_m.is_finite() && velocity_mps.is_finite()) {
            return Err(VisionError::BadValue {
                what: "in-hand truth",
                detail: format!("travel {travel_m} m, velocity {velocity_mps} m/s"),
            });
        }
        let axis = self.sliding_axis_in_hand.into_inner();
        let hand_from_object = Isometry3::from_parts(
            Translation3::from(self.object_start_in_hand + axis * travel_m),
            UnitQuaternion::identity(),
        );
        let (frame, inside, truth) = self.scene.render(&hand_from_object, axis * velocity_mps, t, sequence);
        let true_mask = mask(frame.depth.width, frame.depth.height, &inside)?;
        if !self.started && self.start_at_truth {
            let settings =
                TrackerSettings { initial_pose: Some(truth.camera_from_object), ..self.settings.clone() };
            self.tracker = build_tracker(self.kind, &self.model, &frame.intrinsics, &settings)?;
        }
        let arrivals = self.measurements.on_frame(
            t,
            Some(FrameTruth { camera_from_object: &truth.camera_from_object, mask: &true_mask }),
        )?;
        let state = self.tracker.process(&frame, &arrivals)?;
        self.started = true;
        if let Some(r) = &self.recording {
            if let Some(channels) = &r.rgbd {
                let jpeg = encode_color_jpeg(&frame.color, JPEG_QUALITY)?;
                channels.log_frame(&r.logger, &frame, &jpeg, Some(&truth), Some(&true_mask))?;
                for m in &arrivals.masks {
                    channels.log_vision_mask(&r.logger, m.frame_t, m.arrival_t, &m.value)?;
                }
                for p in &arrivals.poses {
                    channels.log_vision_pose(&r.logger, p.frame_t, p.arrival_t, &p.value)?;
                }
            }
            if let Some(s) = &state {
                r.estimates.log(&r.logger, s)?;
            }
        }
        let hand_from_camera = *self.scene.hand_from_camera();
        let hand_from_object = state.as_ref().map(|s| hand_from_camera * s.estimate.camera_from_object);
        let position_m =
            hand_from_object.map(|h| axis.dot(&(h.translation.vector - self.object_start_in_hand)));
        // The camera does not move in the hand: rotate the object origin's velocity.
        let velocity_mps =
            state.as_ref().map(|s| axis.dot(&(hand_from_camera.rotation * s.estimate.linear_velocity_mps)));
        Ok(InHandStep {
            t,
            state,
            hand_from_object,
            position_m,
            velocity_mps,
            poses_arrived: arrivals.poses.len(),
        })
    }
}
