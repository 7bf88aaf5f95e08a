//! The devices of the replay rig: each implements its driver trait from a
//! recorded channel, on a clock that the tactile scans' log times drive.

use std::path::Path;
use std::sync::Arc;

use slidetrack_control::ObserverError;
use slidetrack_core::{
    ActuatorCommand, ActuatorSpec, Camera, CameraIntrinsics, Clock, DecoderCounters, DeviceError,
    EncodedImage, ErrorKind, Frame, GripperObject, GripperStatus, HandActuator, HandMonitor, HandStatus,
    SimClock, SimTruth, TactileInfo, TactileSample, TactileSource, TruthSource,
};
use slidetrack_session::{
    ArucoDetection, ChannelMessage, CompressedImage, HandState, SimTruth as TruthMsg, TactileDecoder,
    TactileRaw,
};

use super::stream::TopicStream;
use crate::marker::MarkerSource;

/// `/tactile/raw` as a tactile source. Each scan moves the replay clock to
/// its log time.
///
/// # Contract
/// As [`TactileSource`]: scans in recorded order at their log times; at the
/// end of the recording, `Disconnected` ("end of the recording"), like a
/// device that is gone.
pub struct ReplayTactile {
    scans: TopicStream<TactileRaw>,
    decoder: Option<TopicStream<TactileDecoder>>,
    counters: Option<DecoderCounters>,
    clock: SimClock,
    info: TactileInfo,
    device: String,
}

impl ReplayTactile {
    /// The scans of the session at `path`, described by `info` (the recorded
    /// taxel layout), with the recorded decoder counters when `decoder`.
    pub fn open(path: &Path, info: TactileInfo, decoder: bool, clock: SimClock) -> Result<Self, DeviceError> {
        let device = format!("replay of {}", path.display());
        let decoder =
            if decoder { Some(TopicStream::open(path, TactileDecoder::TOPIC, &device)?) } else { None };
        Ok(ReplayTactile {
            scans: TopicStream::open(path, TactileRaw::TOPIC, &device)?,
            decoder,
            counters: None,
            clock,
            info,
            device,
        })
    }
}

impl TactileSource for ReplayTactile {
    fn read(&mut self) -> Result<TactileSample, DeviceError> {
        let Some(scan) = self.scans.next_message()? else {
            return Err(DeviceError::new(ErrorKind::Disconnected, &self.device, "end of the recording"));
        };
        let t = scan.log_time;
        self.clock.sleep_until(t);
        if let Some(stream) = self.decoder.as_mut() {
            while let Some(c) = stream.next_until(t)? {
                let m = c.message;
                self.counters = Some(DecoderCounters {
                    frames: m.frames,
                    crc_errors: m.crc_errors,
                    resyncs: m.resyncs,
                    bytes_skipped: m.bytes_skipped,
                    gaps: m.gaps,
                    incomplete_scans: m.incomplete_scans,
                    invalid_samples: m.invalid_samples,
                });
            }
        }
        let raw = scan.message.scan(&self.info.layout).map_err(|e| {
            DeviceError::new(ErrorKind::Corrupt, &self.info.device, format!("a recorded scan at {t}: {e}"))
        })?;
        Ok(TactileSample::new(t, scan.message.sequence, raw))
    }

    fn info(&self) -> TactileInfo {
        self.info.clone()
    }

    fn counters(&self) -> Option<DecoderCounters> {
        self.decoder.as_ref().and(self.counters)
    }
}

/// `/camera/image` as a camera: the recorded bytes, not decoded, of every
/// frame logged at or before the replay clock.
pub struct ReplayCamera {
    frames: TopicStream<CompressedImage>,
    clock: SimClock,
    intrinsics: CameraIntrinsics,
    device: String,
}

impl ReplayCamera {
    /// The frames of the session at `path`, with the recorded `intrinsics`.
    pub fn open(path: &Path, intrinsics: CameraIntrinsics, clock: SimClock) -> Result<Self, DeviceError> {
        let device = format!("replay of {} camera", path.display());
        let frames = TopicStream::open(path, CompressedImage::TOPIC, &device)?;
        Ok(ReplayCamera { frames, clock, intrinsics, device })
    }
}

impl Camera for ReplayCamera {
    fn poll(&mut self) -> Result<Option<Frame>, DeviceError> {
        let Some(f) = self.frames.next_until(self.clock.now())? else { return Ok(None) };
        let encoded = EncodedImage { format: f.message.format, bytes: f.message.data };
        Ok(Some(Frame {
            t: f.log_time,
            sequence: u64::from(f.sequence),
            pixels: None,
            encoded: Some(encoded),
        }))
    }

    fn intrinsics(&self) -> &CameraIntrinsics {
        &self.intrinsics
    }

    fn device(&self) -> &str {
        &self.device
    }
}

/// `/sim/truth` as the simulator's truth: the record logged with the newest scan.
pub struct ReplayTruth {
    truth: TopicStream<TruthMsg>,
    clock: SimClock,
}

impl ReplayTruth {
    /// The truth of the session at `path`.
    pub fn open(path: &Path, clock: SimClock) -> Result<Self, DeviceError> {
        let truth = TopicStream::open(path, TruthMsg::TOPIC, &format!("replay of {} truth", path.display()))?;
        Ok(ReplayTruth { truth, clock })
    }
}

impl TruthSource for ReplayTruth {
    fn latest(&mut self) -> Option<SimTruth> {
        let t = self.clock.now();
        let m = match self.truth.at(t) {
            Ok(m) => m?.message,
            Err(e) => {
                tracing::warn!("{e}");
                return None;
            }
        };
        Some(SimTruth {
            t,
            position_m: m.position,
            velocity_mps: m.velocity,
            supported: m.supported,
            // Not recorded: the recording's truth comes from an object in the hand.
            dropped: false,
            normal_n: m.normal_force.into_array(),
            friction_n: m.friction_force.into_array(),
        })
    }
}

/// The hand of a replay: takes the commands and releases, moves nothing.
/// It accepts what the recorded rig's hand accepted, so the commands it
/// records are limited as they were.
pub struct ReplayHand {
    spec: ActuatorSpec,
}

impl ReplayHand {
    /// A hand accepting what `spec` says.
    pub fn new(spec: ActuatorSpec) -> ReplayHand {
        ReplayHand { spec }
    }
}

impl HandActuator for ReplayHand {
    fn spec(&self) -> ActuatorSpec {
        self.spec.clone()
    }

    fn command(&mut self, _command: &ActuatorCommand) -> Result<(), DeviceError> {
        Ok(())
    }

    fn release(&mut self) -> Result<(), DeviceError> {
        Ok(())
    }

    fn device(&self) -> &str {
        "replay hand"
    }
}

/// `/hand/state` as the hand's monitor: the status recorded last at or
/// before the replay clock, so the replay reads the hand's state after each
/// scan as the recording did.
///
/// # Contract
/// As [`HandMonitor`]: `status` returns at once, the newest recorded status
/// not yet returned (older ones logged since the last call are skipped), or
/// `None`; a corrupt message is a `Corrupt` error.
pub struct ReplayHandMonitor {
    states: TopicStream<HandState>,
    clock: SimClock,
    device: String,
}

impl ReplayHandMonitor {
    /// The hand states of the session at `path`.
    pub fn open(path: &Path, clock: SimClock) -> Result<Self, DeviceError> {
        let device = format!("replay of {} hand", path.display());
        Ok(ReplayHandMonitor { states: TopicStream::open(path, HandState::TOPIC, &device)?, clock, device })
    }
}

/// The status a `/hand/state` message recorded at `t`.
fn hand_status(t: slidetrack_core::TimeNs, h: HandState) -> HandStatus {
    let gripper = h.gripper.map(|g| GripperStatus {
        activated: g.activated,
        object: GripperObject::from_bits(g.object),
        fault: g.fault,
        requested_steps: g.requested,
        position_steps: g.position,
        current_ma: g.current_ma,
    });
    HandStatus { t, finger_travel_m: h.finger_travel, opening_m: h.opening, gripper }
}

impl HandMonitor for ReplayHandMonitor {
    fn status(&mut self) -> Result<Option<HandStatus>, DeviceError> {
        let now = self.clock.now();
        let mut latest = None;
        while let Some(m) = self.states.next_until(now)? {
            latest = Some(hand_status(m.log_time, m.message));
        }
        Ok(latest)
    }

    fn device(&self) -> &str {
        &self.device
    }
}

/// `/aruco/detections` as a marker source: the detection recorded with each
/// frame, so a replay follows the marker exactly as the recording did
/// (detecting again on the recorded JPEG frames would not).
pub struct RecordedMarkers {
    detections: TopicStream<ArucoDetection>,
    intrinsics: CameraIntrinsics,
}

impl RecordedMarkers {
    /// The detections of the session at `path`, in a camera of `intrinsics`.
    pub fn open(path: &Path, intrinsics: CameraIntrinsics) -> Result<Self, DeviceError> {
        let device = format!("replay of {} markers", path.display());
        Ok(RecordedMarkers {
            detections: TopicStream::open(path, ArucoDetection::TOPIC, &device)?,
            intrinsics,
        })
    }
}

impl MarkerSource for RecordedMarkers {
    fn detect(&mut self, frame: &Frame) -> Result<ArucoDetection, ObserverError> {
        Ok(self.detections.at(frame.t)?.map_or_else(ArucoDetection::missed, |d| d.message))
    }

    fn intrinsics(&self) -> &CameraIntrinsics {
        &self.intrinsics
    }
}

/// The replay clock: simulated time that the tactile scans move.
pub fn replay_clock() -> (SimClock, Arc<dyn Clock>) {
    let clock = SimClock::new();
    (clock.clone(), Arc::new(clock))
}
