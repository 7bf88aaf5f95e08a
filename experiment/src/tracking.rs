//! The live trackers of `slidetrack track`: the dEKF and the grasp-state
//! detector on every tactile scan and a causal constant-velocity Kalman
//! filter on the marker, recorded beside the trial (`/tactile/derivative`,
//! `/estimate/dekf`, `/estimate/slip`, `/estimate/aruco`) and shown in the
//! terminal; beside them a vision
//! tracker, on the simulated rig's rendered in-hand RGB-D scene or, on a
//! hardware rig, on its RGB-D camera in a thread of its own.

use std::sync::{Arc, Mutex};

use anyhow::Result;
use slidetrack_control::{Baseline, ObserverError, ProtocolEvent};
use slidetrack_core::{Frame, HandStatus, Phase, SimTruth, TactileInfo, TimeNs};
use slidetrack_estimators::constant_velocity::{CvFilter, CvParams};
use slidetrack_estimators::dekf::DekfModel;
use slidetrack_estimators::metrics::RunningRms;
use slidetrack_estimators::slip::{GraspDetectorConfig, GraspState};
use slidetrack_session::{
    ArucoEstimate, ChannelHandle, Logger, SlidingEstimate, SlipEstimate, TactileDerivative,
};

use crate::dekf_run::{CM, DekfStage, EstimateChannel, estimate_metadata};
use crate::grasp_state::SlipStage;
use crate::observer::TrialExtension;
use crate::vision_inhand::InHandVision;
use slidetrack_vision::live::LiveThread;

/// Errors accumulated against the simulator's truth.
#[derive(Clone, Copy, Debug, Default)]
pub struct ErrorSums {
    /// Position errors (cm).
    pub position: RunningRms,
    /// Velocity errors (cm/s).
    pub velocity: RunningRms,
    /// Truth positions: the zero-motion baseline's errors (cm).
    pub baseline: RunningRms,
}

impl ErrorSums {
    fn add(&mut self, estimate: [f64; 2], truth: [f64; 2]) {
        self.position.add(estimate[0] - truth[0]);
        self.velocity.add(estimate[1] - truth[1]);
        self.baseline.add(truth[0]);
    }

    /// `(position RMSE cm, velocity RMSE cm/s, baseline position RMSE cm)`.
    pub fn rmse(&self) -> Option<[f64; 3]> {
        Some([self.position.rms()?, self.velocity.rms()?, self.baseline.rms()?])
    }
}

/// What the trackers know now, and their errors so far.
#[derive(Clone, Debug, Default)]
pub struct LiveStatus {
    /// Session time of the last estimate (s).
    pub t_s: f64,
    /// dEKF `(p, v)` (cm, cm/s), 0 where it started.
    pub dekf: Option<[f64; 2]>,
    /// Marker filter `(p, v)` (cm, cm/s), 0 at the first detection.
    pub marker: Option<[f64; 2]>,
    /// Simulator's truth `(p, v)` (cm, cm/s) relative to where the dEKF started.
    pub truth: Option<[f64; 2]>,
    /// dEKF steps.
    pub dekf_steps: u64,
    /// The grasp detector's state after the last scan.
    pub grasp: Option<GraspState>,
    /// dEKF errors against the simulator's truth until the release.
    pub dekf_errors: ErrorSums,
    /// Marker filter errors against the simulator's truth until the release.
    pub marker_errors: ErrorSums,
    /// Vision tracker `(p, v)` along the sliding axis (cm, cm/s), relative to where the dEKF started.
    pub vision: Option<[f64; 2]>,
    /// Vision tracker errors against the simulator's truth until the release.
    pub vision_errors: ErrorSums,
    /// The vision tracker on the rig's RGB-D camera, once its thread ended.
    pub camera_vision: Option<CameraVisionSummary>,
}

/// When the vision tracker on a camera's frames stops.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum VisionEnd {
    /// With the trial (a live camera).
    WithTheTrial,
    /// At the end of its frames, however long after the trial (recorded
    /// frames, which a replay reads faster than real time).
    WithItsFrames,
}

/// What the vision tracker on a rig's RGB-D camera did.
#[derive(Clone, Debug, Default)]
pub struct CameraVisionSummary {
    /// Frames processed.
    pub frames: usize,
    /// Frames with an estimate.
    pub tracked: usize,
    /// Frames per second of the tracker alone.
    pub tracker_fps: f64,
    /// The measurement source's summary line.
    pub measurements: Option<String>,
    /// Why the loop stopped before the trial did, if it did.
    pub error: Option<String>,
}

impl CameraVisionSummary {
    /// Stops `thread` as `end` says and sums up what it did.
    pub fn of(thread: LiveThread, end: VisionEnd) -> CameraVisionSummary {
        let ended = match end {
            VisionEnd::WithTheTrial => thread.stop(),
            VisionEnd::WithItsFrames => thread.wait_for_end(),
        };
        match ended {
            Ok((tracking, ended)) => {
                let counts = tracking.counts();
                CameraVisionSummary {
                    frames: counts.frames,
                    tracked: counts.tracked,
                    tracker_fps: counts.tracker_fps(),
                    measurements: tracking.measurement_summary(),
                    error: ended.err().map(|e| e.to_string()),
                }
            }
            Err(e) => CameraVisionSummary { error: Some(e.to_string()), ..CameraVisionSummary::default() },
        }
    }
}

/// Shortest session time between two redraws of the live line (s).
const DRAW_PERIOD_S: f64 = 0.1;

/// The dEKF and the marker filter as a [`TrialExtension`].
pub struct LiveTrackers {
    logger: Logger,
    dekf: DekfStage,
    derivative_ch: ChannelHandle<TactileDerivative>,
    dekf_ch: EstimateChannel,
    /// The grasp-state detector and `/estimate/slip`.
    slip: SlipStage,
    slip_ch: ChannelHandle<SlipEstimate>,
    marker: Option<(CvFilter, ChannelHandle<ArucoEstimate>)>,
    vision: Option<InHandVision>,
    /// The vision tracker on the rig's RGB-D camera, stopped when the
    /// trackers are dropped (before the session is finished).
    camera_vision: Option<(LiveThread, VisionEnd)>,
    /// Latest simulator truth `(p, v)` (m, m/s) and its position when the dEKF started.
    truth: Option<[f64; 2]>,
    truth_origin: Option<f64>,
    released: bool,
    status: Arc<Mutex<LiveStatus>>,
    display: Box<dyn FnMut(&str)>,
    drawn_at: f64,
}

impl LiveTrackers {
    /// Registers the estimate channels on `logger` (the grasp detector with
    /// its default settings on `/estimate/slip`); `marker` adds the marker
    /// filter and `/estimate/aruco`. `status` is shared with the caller for
    /// the summary; `display` receives the live line (about ten times per
    /// second of session time).
    pub fn new(
        logger: &Logger,
        tactile: &TactileInfo,
        model: &DekfModel,
        model_name: &str,
        marker: Option<CvParams>,
        status: Arc<Mutex<LiveStatus>>,
        display: Box<dyn FnMut(&str)>,
    ) -> Result<LiveTrackers> {
        let [derivative_meta, estimate_meta] = estimate_metadata(model, model_name)?;
        let marker = match marker {
            Some(params) => {
                let meta = std::collections::BTreeMap::from([(
                    "filter".to_string(),
                    format!(
                        "causal constant-velocity KF (eq. 6.13) on /aruco/detections: q_p {} m^2/s, q_v {} m^2/s^3, R {} m^2, gate {:?}",
                        params.q_position_m2_per_s,
                        params.q_velocity_m2_per_s3,
                        params.r_m2,
                        params.gate.map(|g| g.max_mahalanobis2)
                    ),
                )]);
                Some((CvFilter::new(params), logger.register::<ArucoEstimate>(meta)?))
            }
            None => None,
        };
        let slip = SlipStage::new(GraspDetectorConfig::default(), tactile)?;
        let slip_ch = logger.register::<SlipEstimate>(slip.metadata()?)?;
        Ok(LiveTrackers {
            slip,
            slip_ch,
            logger: logger.clone(),
            dekf: DekfStage::new(model, tactile)?,
            derivative_ch: logger.register::<TactileDerivative>(derivative_meta)?,
            dekf_ch: EstimateChannel::register(logger, model, estimate_meta)?,
            marker,
            vision: None,
            camera_vision: None,
            truth: None,
            truth_origin: None,
            released: false,
            status,
            display,
            drawn_at: f64::NEG_INFINITY,
        })
    }

    /// Also runs a vision tracker on the simulated in-hand RGB-D scene at
    /// each camera frame (it records its own channels).
    pub fn with_vision(mut self, vision: InHandVision) -> LiveTrackers {
        self.vision = Some(vision);
        self
    }

    /// Also runs a vision tracker on the rig's RGB-D camera, on its own
    /// thread (recording to the session itself); its summary goes to the
    /// status once the trackers are dropped.
    pub fn with_camera_vision(mut self, thread: LiveThread, end: VisionEnd) -> LiveTrackers {
        self.camera_vision = Some((thread, end));
        self
    }

    /// The vision tracker's step at a camera frame.
    fn vision_step(&mut self, frame: &Frame) -> Result<(), ObserverError> {
        let (Some(vision), Some([p, v])) = (self.vision.as_mut(), self.truth) else { return Ok(()) };
        let step = vision.on_frame(frame.t, frame.sequence, p, v)?;
        let (Some(p), Some(v)) = (step.position_m, step.velocity_mps) else { return Ok(()) };
        let origin = self.truth_origin.unwrap_or(0.0);
        let estimate = [(p - origin) * CM, v * CM];
        let truth = self.truth_cm();
        let released = self.released;
        self.with_status(|s| {
            s.vision = Some(estimate);
            if let (Some(tr), false) = (truth, released) {
                s.vision_errors.add(estimate, tr);
            }
        });
        Ok(())
    }

    /// The simulator's truth relative to where the dEKF started (cm, cm/s).
    fn truth_cm(&self) -> Option<[f64; 2]> {
        let (t, o) = (self.truth?, self.truth_origin?);
        Some([(t[0] - o) * CM, t[1] * CM])
    }

    fn draw(&mut self, s: &LiveStatus) {
        if s.t_s - self.drawn_at < DRAW_PERIOD_S {
            return;
        }
        self.drawn_at = s.t_s;
        let fmt = |x: Option<[f64; 2]>| {
            x.map_or_else(
                || "      -                 ".to_string(),
                |[p, v]| format!("{p:+6.2} cm {v:+6.2} cm/s"),
            )
        };
        let mut line = format!("{:6.1} s  dEKF {}", s.t_s, fmt(s.dekf));
        if self.marker.is_some() {
            line += &format!("  | marker {}", fmt(s.marker));
        }
        if self.vision.is_some() {
            line += &format!("  | vision {}", fmt(s.vision));
        }
        if let Some(grasp) = s.grasp {
            line += &format!("  | grasp {}", grasp.as_str());
        }
        if s.truth.is_some() {
            line += &format!("  | truth {}", fmt(s.truth));
        }
        (self.display)(&line);
    }

    fn with_status(&mut self, f: impl FnOnce(&mut LiveStatus)) {
        let snapshot = match self.status.lock() {
            Ok(mut s) => {
                f(&mut s);
                s.clone()
            }
            Err(_) => return,
        };
        self.draw(&snapshot);
    }
}

impl Drop for LiveTrackers {
    /// Stops the camera's vision thread, if any, and keeps its summary.
    fn drop(&mut self) {
        let Some((thread, end)) = self.camera_vision.take() else { return };
        let summary = CameraVisionSummary::of(thread, end);
        if let Ok(mut s) = self.status.lock() {
            s.camera_vision = Some(summary);
        }
    }
}

impl TrialExtension for LiveTrackers {
    fn on_zeroed(&mut self, t: TimeNs, zeroed: &Baseline) -> Result<(), ObserverError> {
        let slip = self.slip.on_scan(t, zeroed);
        self.logger.log_json(&self.slip_ch, t, t, 0, &slip)?;
        let grasp = self.slip.reading().state;
        let Some(out) = self.dekf.on_scan(t, zeroed) else { return Ok(()) };
        let msg = TactileDerivative { values: out.measurement.clone() };
        self.logger.log_json(&self.derivative_ch, t, t, 0, &msg)?;
        self.dekf_ch.log(&self.logger, t, &out)?;
        if self.truth_origin.is_none() {
            self.truth_origin = self.truth.map(|x| x[0]);
        }
        let truth = self.truth_cm();
        let released = self.released;
        self.with_status(|s| {
            s.t_s = out.t_s;
            // Position and rate of the first degree of freedom (sliding:
            // along the axis; planar: along the contact frame's x).
            let dofs = out.dim() / 2;
            s.dekf = Some([out.mean[0], out.mean[dofs]]);
            s.truth = truth;
            s.dekf_steps += 1;
            s.grasp = Some(grasp);
            // The simulator's truth is along the sliding axis: a planar
            // model's state is not scored against it.
            if let (Some(tr), false, 1) = (truth, released, dofs) {
                s.dekf_errors.add([out.mean[0], out.mean[1]], tr);
            }
        });
        Ok(())
    }

    fn on_frame(&mut self, frame: &Frame, position_on_axis_m: Option<f64>) -> Result<(), ObserverError> {
        self.vision_step(frame)?;
        let Some((filter, ch)) = self.marker.as_mut() else { return Ok(()) };
        let Some(b) = filter.step(frame.t.as_secs_f64(), position_on_axis_m) else { return Ok(()) };
        let msg = ArucoEstimate(SlidingEstimate {
            position: b.mean[0],
            velocity: b.mean[1],
            covariance: [[b.cov[(0, 0)], b.cov[(0, 1)]], [b.cov[(1, 0)], b.cov[(1, 1)]]],
        });
        self.logger.log_json(ch, frame.t, frame.t, 0, &msg)?;
        let estimate = [b.mean[0] * CM, b.mean[1] * CM];
        let truth = self.truth_cm();
        let released = self.released;
        self.with_status(|s| {
            s.marker = Some(estimate);
            if let (Some(tr), false) = (truth, released) {
                s.marker_errors.add(estimate, tr);
            }
        });
        Ok(())
    }

    fn on_hand_status(&mut self, status: &HandStatus) {
        self.slip.set_opening(status.opening_m);
    }

    fn on_truth(&mut self, truth: &SimTruth) {
        self.truth = Some([truth.position_m, truth.velocity_mps]);
    }

    fn on_event(&mut self, _t: TimeNs, event: &ProtocolEvent) {
        if matches!(event.phase, Phase::Release | Phase::Aborted | Phase::Done) {
            self.released = true;
        }
        self.slip.protocol_event(&event.phase);
    }
}
