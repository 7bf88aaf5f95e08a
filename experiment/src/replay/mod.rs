//! The replay rig: a recorded session played back through the same driver
//! traits as the live rigs, on a clock driven by the recording's log times
//! (as copper-rs's resim does), so that everything downstream of the devices
//! (the protocol, the observers, the online estimators) runs on a recording
//! exactly as it ran live.
//!
//! - `/tactile/raw` is the tactile source; each scan moves the clock to its
//!   log time. The protocol runs again on these scans and computes the same
//!   baseline, zeroed channels, control ticks and commands as live.
//! - `/camera/image` is the camera (the recorded bytes, not decoded) and
//!   `/aruco/detections` the marker source: the marker filter sees the
//!   detections the recording saw.
//! - `/sim/truth` is the simulator's truth, when the session has it.
//! - `/hand/state` is the hand's monitor, when the session has it: the
//!   observers read the recorded status after each scan, as live.
//! - The hand takes commands and moves nothing.
//!
//! A replay is as deterministic as the code it runs: `track --rig replay` on
//! a session recorded by `track` gives the same estimates, message for message.

mod devices;
mod stream;

use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;

use anyhow::{Context, Result, bail};
use slidetrack_control::{
    Baseline, ControlRecord, ObserverError, Protocol, ProtocolEvent, Rig, Tare, TrialObserver, TrialOutcome,
    run_trial,
};
use slidetrack_core::{
    ActuatorCommand, DecoderCounters, Frame, HandStatus, Phase, SimTruth, TactileInfo, TactileSample, TimeNs,
};
use slidetrack_estimators::dekf::{DekfModel, DekfOutput};
use slidetrack_estimators::slip::GraspDetectorConfig;
use slidetrack_session::{
    ArucoDetection, CameraCalibration, ChannelMessage, CompressedImage, HandState, ProtocolEvent as EventMsg,
    ReadOptions, SESSION_METADATA, SessionInfo, SimTruth as TruthMsg, SlipEstimate, TactileDecoder,
    TactileRaw, read_channel,
};
use slidetrack_sim::ObjectConfig;

pub use devices::{RecordedMarkers, ReplayCamera, ReplayHand, ReplayHandMonitor, ReplayTactile, ReplayTruth};
pub use stream::{Recorded, TopicStream};

use crate::channels::recorded_tactile;
use crate::dekf_run::DekfStage;
use crate::grasp_state::SlipStage;
use crate::marker::MarkerSource;
use crate::observer::TrialExtension;
use crate::rig::{RigSetup, TrialSpec, configured_actuator, protocol_for};
use crate::rig_config::RigConfig;
use crate::trial::CYCLES_DURATION_KEY;

/// A recorded session, ready to be replayed: what its rig, object and
/// protocol were, and which of the replayed channels it has.
#[derive(Clone, Debug)]
pub struct ReplaySession {
    /// The session file.
    pub path: PathBuf,
    /// The rig configuration it was recorded with.
    pub rig: RigConfig,
    /// Its object.
    pub object: ObjectConfig,
    /// The seed of its simulated rig (0 for a real rig).
    pub seed: u64,
    /// Its trial number.
    pub trial: u32,
    /// The duration of its sliding cycles (s); infinite when the recording
    /// does not say (the replay then runs to the end of the recording).
    pub cycles_duration_s: f64,
    /// The recorded tactile source.
    pub tactile: TactileInfo,
    /// The camera's intrinsics, when it recorded camera frames and marker detections.
    pub camera: Option<slidetrack_core::CameraIntrinsics>,
    /// True when it has the simulator's truth.
    pub has_truth: bool,
    /// True when it has the tactile decoder's counters.
    pub has_decoder: bool,
    /// True when it has the hand's states (`/hand/state`).
    pub has_hand_state: bool,
}

/// Which recorded devices a replay plays.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ReplayOptions {
    /// The camera and the marker detections (when recorded).
    pub camera: bool,
    /// The simulator's truth (when recorded).
    pub truth: bool,
}

impl Default for ReplayOptions {
    /// Every recorded device.
    fn default() -> Self {
        ReplayOptions { camera: true, truth: true }
    }
}

impl ReplaySession {
    /// Reads what `path` holds; fails when it has no raw tactile scans.
    pub fn open(path: &Path) -> Result<ReplaySession> {
        let info = SessionInfo::read(path, ReadOptions::default())?;
        let has = |topic: &str| info.channel(topic).is_some_and(|c| c.message_count > 0);
        if !has(TactileRaw::TOPIC) {
            bail!("{} has no {} to replay", path.display(), TactileRaw::TOPIC);
        }
        let meta = info.metadata.get(SESSION_METADATA).cloned().unwrap_or_default();
        let origin = |what: &str| format!("{} metadata {what}", path.display());
        let rig = match meta.get("rig_config").filter(|t| !t.trim().is_empty()) {
            Some(text) => slidetrack_core::parse_toml(text, &origin("rig_config"))?,
            None => RigConfig::default(),
        };
        let object = match meta.get("object_config").filter(|t| !t.trim().is_empty()) {
            Some(text) => ObjectConfig::from_toml(text, &origin("object_config"))?,
            None => ObjectConfig::load(meta.get("object").map_or("box", String::as_str))?,
        };
        let tactile = recorded_tactile(path, &info)?.unwrap_or_else(|| {
            TactileInfo::one_module_per_finger("recorded", rig.sim.tactile_rate_hz, "sim")
        });
        let camera = if has(CompressedImage::TOPIC) && has(ArucoDetection::TOPIC) {
            let calibration = read_channel::<CameraCalibration>(path, ReadOptions::default())?;
            calibration.first().and_then(|(_, c)| c.intrinsics())
        } else {
            None
        };
        Ok(ReplaySession {
            path: path.to_path_buf(),
            seed: meta.get("seed").and_then(|s| s.parse().ok()).unwrap_or(0),
            trial: meta.get("trial").and_then(|s| s.parse().ok()).unwrap_or(0),
            cycles_duration_s: cycles_duration(path, &meta)?,
            rig,
            object,
            tactile,
            camera,
            has_truth: has(TruthMsg::TOPIC),
            has_decoder: has(TactileDecoder::TOPIC),
            has_hand_state: has(HandState::TOPIC),
        })
    }

    /// The trial this session recorded, to be recorded again at `out`.
    pub fn trial_spec(&self, out: PathBuf, overwrite: bool) -> TrialSpec<'_> {
        TrialSpec {
            rig: &self.rig,
            object: &self.object,
            seed: self.seed,
            trial: self.trial,
            duration_s: self.cycles_duration_s,
            camera: self.camera.is_some(),
            realtime: false,
            overwrite,
            path: out,
            live: None,
        }
    }

    /// The replay rig of this session.
    pub fn rig(&self, options: ReplayOptions) -> Result<RigSetup> {
        let (clock, shared_clock) = devices::replay_clock();
        let path = &self.path;
        let tactile = ReplayTactile::open(path, self.tactile.clone(), self.has_decoder, clock.clone())?;
        let (camera, markers) = match (&self.camera, options.camera) {
            (Some(intrinsics), true) => {
                let camera = ReplayCamera::open(path, intrinsics.clone(), clock.clone())?;
                let markers = RecordedMarkers::open(path, intrinsics.clone())?;
                (
                    Some(Box::new(camera) as Box<dyn slidetrack_core::Camera>),
                    Some(Box::new(markers) as Box<dyn MarkerSource>),
                )
            }
            _ => (None, None),
        };
        let hand_monitor = if self.has_hand_state {
            Some(Box::new(ReplayHandMonitor::open(path, clock.clone())?)
                as Box<dyn slidetrack_core::HandMonitor>)
        } else {
            None
        };
        let truth = if self.has_truth && options.truth {
            Some(Box::new(ReplayTruth::open(path, clock)?) as Box<dyn slidetrack_core::TruthSource>)
        } else {
            None
        };
        let rig = Rig {
            tactile: Box::new(tactile),
            hand: Box::new(ReplayHand::new(configured_actuator(&self.rig))),
            camera,
            clock: shared_clock,
            truth,
            hand_monitor,
        };
        let extra_metadata =
            std::collections::BTreeMap::from([("replay_of".to_string(), self.path.display().to_string())]);
        Ok(RigSetup {
            rig,
            tactile_info: self.tactile.clone(),
            markers,
            rig_name: "replay".into(),
            extra_metadata,
            rgbd: None,
            rgbd_frames: None,
            image_encoder: None,
        })
    }

    /// The protocol the recording ran.
    pub fn protocol(&self) -> Result<Protocol> {
        let fingers = self.tactile.finger_map().context("the recorded taxel layout")?;
        Ok(protocol_for(
            &self.rig,
            &self.object,
            self.cycles_duration_s,
            fingers,
            &configured_actuator(&self.rig),
        ))
    }
}

/// The cycles' duration: recorded in the metadata by recent versions, else
/// the time from entering the cycles to the release, which makes the
/// protocol release at the same scan; infinite when the trial never released.
fn cycles_duration(path: &Path, meta: &std::collections::BTreeMap<String, String>) -> Result<f64> {
    if let Some(d) = meta.get(CYCLES_DURATION_KEY).and_then(|s| s.parse::<f64>().ok()) {
        return Ok(d);
    }
    let events = match read_channel::<EventMsg>(path, ReadOptions::default()) {
        Ok(events) => events,
        Err(slidetrack_session::SessionError::NoSuchTopic { .. }) => Vec::new(),
        Err(e) => return Err(e.into()),
    };
    let at = |phase: Phase| events.iter().find(|(_, e)| e.phase == phase && !e.abort).map(|(t, _)| *t);
    Ok(match (at(Phase::Cycles), at(Phase::Release)) {
        (Some(cycles), Some(release)) => release.secs_since(cycles),
        _ => f64::INFINITY,
    })
}

/// A trial observer that records nothing: it feeds the replayed data to an
/// extension (the online estimators) with the recorded marker detections.
struct ExtensionObserver<'a> {
    markers: Option<Box<dyn MarkerSource>>,
    extension: &'a mut dyn TrialExtension,
}

impl TrialObserver for ExtensionObserver<'_> {
    fn on_tactile(&mut self, _sample: &TactileSample) -> Result<(), ObserverError> {
        Ok(())
    }

    fn on_truth(&mut self, truth: &SimTruth) -> Result<(), ObserverError> {
        self.extension.on_truth(truth);
        Ok(())
    }

    fn on_tare(&mut self, _t: TimeNs, _tare: &Tare) -> Result<(), ObserverError> {
        Ok(())
    }

    fn on_zeroed(&mut self, t: TimeNs, zeroed: &Baseline) -> Result<(), ObserverError> {
        self.extension.on_zeroed(t, zeroed)
    }

    fn on_control(&mut self, _t: TimeNs, _record: &ControlRecord) -> Result<(), ObserverError> {
        Ok(())
    }

    fn on_command(
        &mut self,
        _t: TimeNs,
        _command: &ActuatorCommand,
        _limited: bool,
    ) -> Result<(), ObserverError> {
        Ok(())
    }

    fn on_frame(&mut self, frame: Frame) -> Result<Option<f64>, ObserverError> {
        let detection = match self.markers.as_mut() {
            Some(m) => m.detect(&frame)?,
            None => ArucoDetection::missed(),
        };
        self.extension.on_frame(&frame, detection.position_on_axis_m)?;
        Ok(detection.position_on_axis_m)
    }

    fn on_event(&mut self, t: TimeNs, event: &ProtocolEvent) -> Result<(), ObserverError> {
        self.extension.on_event(t, event);
        Ok(())
    }

    fn on_decoder(&mut self, _t: TimeNs, _counters: &DecoderCounters) -> Result<(), ObserverError> {
        Ok(())
    }

    fn on_hand_status(&mut self, status: &HandStatus) -> Result<(), ObserverError> {
        self.extension.on_hand_status(status);
        Ok(())
    }
}

/// Replays `session` with `extension` running on it, recording nothing.
pub fn replay_with(
    session: &ReplaySession,
    options: ReplayOptions,
    extension: &mut dyn TrialExtension,
) -> Result<TrialOutcome> {
    let RigSetup { mut rig, markers, .. } = session.rig(options)?;
    let mut observer = ExtensionObserver { markers, extension };
    let mut protocol = session.protocol()?;
    Ok(run_trial(&mut rig, &mut protocol, &mut observer, &AtomicBool::new(false)))
}

/// Collects the estimates of a replay: the dEKF's and the grasp detector's.
#[derive(Default)]
struct EstimateCollector {
    dekf: Option<DekfStage>,
    slip: Option<SlipStage>,
    estimates: ReplayEstimates,
}

impl TrialExtension for EstimateCollector {
    fn on_zeroed(&mut self, t: TimeNs, zeroed: &Baseline) -> Result<(), ObserverError> {
        if let Some(out) = self.dekf.as_mut().and_then(|d| d.on_scan(t, zeroed)) {
            self.estimates.dekf.push((t, out));
        }
        if let Some(slip) = self.slip.as_mut() {
            self.estimates.slip.push((t, slip.on_scan(t, zeroed)));
        }
        Ok(())
    }

    fn on_frame(&mut self, _frame: &Frame, _position_on_axis_m: Option<f64>) -> Result<(), ObserverError> {
        Ok(())
    }

    fn on_hand_status(&mut self, status: &HandStatus) {
        if let Some(slip) = self.slip.as_mut() {
            slip.set_opening(status.opening_m);
        }
    }

    fn on_event(&mut self, _t: TimeNs, event: &ProtocolEvent) {
        if let Some(slip) = self.slip.as_mut() {
            slip.protocol_event(&event.phase);
        }
    }
}

/// The estimates of a replay, at the log times of their scans.
#[derive(Clone, Debug, Default)]
pub struct ReplayEstimates {
    /// The dEKF's, at every filter step (none without a model).
    pub dekf: Vec<(TimeNs, DekfOutput)>,
    /// The grasp detector's (`/estimate/slip`), at every zeroed scan (none
    /// without its settings).
    pub slip: Vec<(TimeNs, SlipEstimate)>,
}

/// The dEKF `model` on a replay of the session at `path`: its estimates at
/// every filter step of the whole recording, as `track` computed them live.
pub fn replay_dekf(path: &Path, model: &DekfModel) -> Result<Vec<(TimeNs, DekfOutput)>> {
    Ok(replay_estimates(path, Some(model), None)?.dekf)
}

/// The dEKF `model` and the grasp detector with `slip` settings (either,
/// both) on a replay of the session at `path`, as `track` runs them live:
/// the dEKF reads the tactile scans, the detector also the recorded hand
/// states (`/hand/state`), one after each scan.
pub fn replay_estimates(
    path: &Path,
    model: Option<&DekfModel>,
    slip: Option<GraspDetectorConfig>,
) -> Result<ReplayEstimates> {
    let session = ReplaySession::open(path)?;
    let mut collector = EstimateCollector::default();
    if let Some(model) = model {
        check_rate(&session, model)?;
        collector.dekf = Some(DekfStage::new(model, &session.tactile)?);
    }
    if let Some(cfg) = slip {
        collector.slip = Some(SlipStage::new(cfg, &session.tactile)?);
    }
    // The estimators read tactile data and the hand only: no camera, no truth.
    let outcome = replay_with(&session, ReplayOptions { camera: false, truth: false }, &mut collector)?;
    let estimates = collector.estimates;
    if let Some(reason) = outcome.abort.filter(|_| estimates.dekf.is_empty() && estimates.slip.is_empty()) {
        bail!("{}: the replay ended before the estimators ran: {reason}", path.display());
    }
    Ok(estimates)
}

/// Checks that `model` was trained at the session's tactile rate.
pub fn check_rate(session: &ReplaySession, model: &DekfModel) -> Result<()> {
    let (rate, expected) = (session.tactile.rate_hz, model.meta.tactile_rate_hz);
    if (rate - expected).abs() > crate::dekf_run::rate_tolerance(model) * expected {
        bail!(
            "{}: tactile rate {rate:.1} Hz, but the model was trained at {expected:.1} Hz (decimation {})",
            session.path.display(),
            model.meta.decimation
        );
    }
    Ok(())
}
