//! Records everything a trial produces into its session, with the marker
//! detection of each camera frame on the way.

use std::collections::BTreeMap;

use anyhow::Result;
use slidetrack_calibration::tactile_force::TactileForceCalibration;
use slidetrack_control::{Baseline, ControlRecord, ObserverError, ProtocolEvent, Tare, TrialObserver};
use slidetrack_core::{
    ActuatorCommand, DecoderCounters, Frame, HandStatus, PerFinger, SimTruth, TactileInfo, TactileLayout,
    TactileSample, TimeNs,
};
use slidetrack_session::{
    ArucoDetection, CameraCalibration, ChannelHandle, ChannelMessage, CompressedImage, FingerSetpoint,
    GraspControl, GripperCommand, HandCommand, HandState, Logger, ProtocolEvent as EventMsg,
    SimTruth as TruthMsg, TactileCalibrated, TactileDecoder, TactileDeviceTime, TactileRaw, TactileReference,
    TactileTare, TactileZeroed, TaxelLayout, sensor_taxels,
};

use crate::image_encoder::{ImageEncodeFn, ImageEncoderThread};
use crate::marker::MarkerSource;

/// What a trial recorded, for the summary line.
#[derive(Clone, Debug, Default)]
pub struct TrialStats {
    /// Tactile scans.
    pub scans: u64,
    /// Camera frames.
    pub frames: u64,
    /// Frames in which the marker was found.
    pub detections: u64,
    /// Largest marker travel seen (m).
    pub max_marker_travel_m: f64,
    /// The simulator's truth, `(t, position m, velocity m/s)` at each scan.
    pub truth: Vec<(TimeNs, f64, f64)>,
    /// Session time of the release (the end of the cycles), if reached.
    pub release_at: Option<TimeNs>,
    /// The tactile decoder's last counters (real devices only).
    pub decoder: Option<DecoderCounters>,
}

/// The channels of the controlled-sliding protocol (none in `slidetrack record`).
struct ControlChannels {
    tare: ChannelHandle<TactileTare>,
    zeroed: ChannelHandle<TactileZeroed>,
    grasp: ChannelHandle<GraspControl>,
    /// `/hand/command`, registered with the first voltages (voltage-driven hands).
    command: Option<ChannelHandle<HandCommand>>,
    /// `/hand/gripper`, registered with the first request (grippers).
    gripper: Option<ChannelHandle<GripperCommand>>,
}

struct Channels {
    raw: ChannelHandle<TactileRaw>,
    control: Option<ControlChannels>,
    events: ChannelHandle<EventMsg>,
    /// `/hand/state`, registered with the first status.
    hand_state: Option<ChannelHandle<HandState>>,
    truth: Option<ChannelHandle<TruthMsg>>,
    image: Option<ChannelHandle<CompressedImage>>,
    calibration: Option<ChannelHandle<CameraCalibration>>,
    aruco: Option<ChannelHandle<ArucoDetection>>,
    /// `/tactile/decoder`, registered with the first counters.
    decoder: Option<ChannelHandle<TactileDecoder>>,
    /// `/tactile/calibrated`, registered with the first scan that carries forces.
    calibrated: Option<ChannelHandle<TactileCalibrated>>,
    /// `/tactile/device_time`, registered with the first scan that carries a device time.
    device_time: Option<ChannelHandle<TactileDeviceTime>>,
    /// `/tactile/reference`, registered with the first scan that carries reference forces.
    reference: Option<ChannelHandle<TactileReference>>,
}

/// Live work on a trial's data beside the recording (the online trackers of
/// `slidetrack track`). The hooks run on the control loop's thread after the
/// data they receive has been recorded; an error ends the trial with a safe
/// release, like a recording error.
pub trait TrialExtension {
    /// A baseline-subtracted tactile scan (counts, `[taxel][x, y, z]` in the
    /// order of the tactile source's layout).
    fn on_zeroed(&mut self, t: TimeNs, zeroed: &Baseline) -> Result<(), ObserverError>;
    /// A camera frame and the marker position along the sliding axis found
    /// in it (m), `None` when the marker was not found.
    fn on_frame(&mut self, frame: &Frame, position_on_axis_m: Option<f64>) -> Result<(), ObserverError>;
    /// The simulator's truth at a scan (simulated rig only).
    fn on_truth(&mut self, _truth: &SimTruth) {}
    /// A protocol event.
    fn on_event(&mut self, _t: TimeNs, _event: &ProtocolEvent) {}
    /// A status the hand reported (read after the scan of its time).
    fn on_hand_status(&mut self, _status: &HandStatus) {}
}

/// Longest time between two `/tactile/decoder` messages while nothing changes (s).
const DECODER_LOG_PERIOD_S: f64 = 1.0;

/// The channel in `slot`, registered on `logger` on first use (channels
/// that only some devices feed appear only in their sessions).
fn registered<'c, T: ChannelMessage>(
    logger: &Logger,
    slot: &'c mut Option<ChannelHandle<T>>,
) -> Result<&'c ChannelHandle<T>, ObserverError> {
    match slot {
        Some(ch) => Ok(ch),
        None => Ok(slot.insert(logger.register::<T>(BTreeMap::new())?)),
    }
}

/// A [`TrialObserver`] that records to a session.
pub struct SessionObserver<'a> {
    logger: Logger,
    ch: Channels,
    marker: Option<Box<dyn MarkerSource + 'a>>,
    stats: TrialStats,
    progress: Box<dyn FnMut(TimeNs) + 'a>,
    /// When the decoder counters were last written, and what they were.
    decoder_written: Option<(TimeNs, DecoderCounters)>,
    extension: Option<Box<dyn TrialExtension + 'a>>,
    /// The tactile sensors, to name them in the tactile channels.
    layout: TactileLayout,
    /// The rig's own force calibration: `/tactile/calibrated` from every
    /// tared scan (and a device's own forces are not recorded).
    force_calibration: Option<TactileForceCalibration>,
    /// The scan counter of the latest scan.
    last_sequence: u64,
    /// Encodes the frames that come without their image (see [`SessionObserver::with_image_encoder`]).
    image_encoder: Option<ImageEncoderThread>,
}

impl<'a> SessionObserver<'a> {
    /// Registers the session's channels. `camera` carries the intrinsics and
    /// marker detection when the trial has a camera; `with_truth` adds `/sim/truth`.
    pub fn new(
        logger: Logger,
        tactile: &TactileInfo,
        camera: Option<Box<dyn MarkerSource + 'a>>,
        with_truth: bool,
        progress: Box<dyn FnMut(TimeNs) + 'a>,
    ) -> Result<SessionObserver<'a>> {
        Self::with_channels(logger, tactile, camera, with_truth, progress, true)
    }

    /// An observer of a recording without the protocol (`slidetrack record`):
    /// the channels of [`SessionObserver::new`] except tare, zeroed, control
    /// and hand command.
    pub fn recording(
        logger: Logger,
        tactile: &TactileInfo,
        camera: Option<Box<dyn MarkerSource + 'a>>,
        with_truth: bool,
        progress: Box<dyn FnMut(TimeNs) + 'a>,
    ) -> Result<SessionObserver<'a>> {
        Self::with_channels(logger, tactile, camera, with_truth, progress, false)
    }

    fn with_channels(
        logger: Logger,
        tactile: &TactileInfo,
        camera: Option<Box<dyn MarkerSource + 'a>>,
        with_truth: bool,
        progress: Box<dyn FnMut(TimeNs) + 'a>,
        with_control: bool,
    ) -> Result<SessionObserver<'a>> {
        let none = BTreeMap::new;
        let layout = TaxelLayout::new(tactile).channel_metadata();
        let raw = logger.register::<TactileRaw>(layout)?;
        let control = with_control
            .then(|| -> Result<ControlChannels> {
                Ok(ControlChannels {
                    tare: logger.register::<TactileTare>(none())?,
                    zeroed: logger.register::<TactileZeroed>(none())?,
                    grasp: logger.register::<GraspControl>(none())?,
                    command: None,
                    gripper: None,
                })
            })
            .transpose()?;
        let ch = Channels {
            raw,
            control,
            events: logger.register::<EventMsg>(none())?,
            hand_state: None,
            truth: with_truth.then(|| logger.register::<TruthMsg>(none())).transpose()?,
            image: camera.as_ref().map(|_| logger.register::<CompressedImage>(none())).transpose()?,
            calibration: camera.as_ref().map(|_| logger.register::<CameraCalibration>(none())).transpose()?,
            aruco: camera.as_ref().map(|_| logger.register::<ArucoDetection>(none())).transpose()?,
            decoder: None,
            calibrated: None,
            device_time: None,
            reference: None,
        };
        if let (Some(c), Some(m)) = (&ch.calibration, &camera) {
            logger.log_json(
                c,
                TimeNs::ZERO,
                TimeNs::ZERO,
                0,
                &CameraCalibration::new(TimeNs::ZERO, "camera", m.intrinsics()),
            )?;
        }
        Ok(SessionObserver {
            logger,
            ch,
            marker: camera,
            stats: TrialStats::default(),
            progress,
            decoder_written: None,
            extension: None,
            layout: tactile.layout.clone(),
            force_calibration: None,
            last_sequence: 0,
            image_encoder: None,
        })
    }

    /// Runs `extension` on the trial's data as it is recorded.
    pub fn with_extension(mut self, extension: Box<dyn TrialExtension + 'a>) -> SessionObserver<'a> {
        self.extension = Some(extension);
        self
    }

    /// Encodes the frames that come with pixels and no image (the simulated
    /// camera of a trial that is not in real time) with `encode`, on a
    /// thread of its own; the session is the same as if the camera had
    /// encoded them, except that none is ever dropped.
    pub fn with_image_encoder(mut self, encode: Option<ImageEncodeFn>) -> Result<SessionObserver<'a>> {
        self.image_encoder = encode.map(ImageEncoderThread::start).transpose()?;
        Ok(self)
    }

    /// Records `/tactile/calibrated` from every tared scan through
    /// `calibration` (checked against the tactile layout), instead of the
    /// forces a device may send.
    pub fn with_force_calibration(
        mut self,
        calibration: TactileForceCalibration,
    ) -> Result<SessionObserver<'a>, slidetrack_calibration::tactile_force::TactileForceError> {
        calibration.check_layout(&self.layout)?;
        self.force_calibration = Some(calibration);
        Ok(self)
    }

    /// Writes the decoder's latest counters at `t` unless they were written already.
    fn flush_decoder(&mut self, t: TimeNs) -> Result<(), ObserverError> {
        let (Some(ch), Some(latest)) = (&self.ch.decoder, self.stats.decoder) else { return Ok(()) };
        if self.decoder_written.is_some_and(|(_, c)| c == latest) {
            return Ok(());
        }
        self.logger.log_json(ch, t, t, 0, &TactileDecoder::from(&latest))?;
        self.decoder_written = Some((t, latest));
        Ok(())
    }

    /// What was recorded so far.
    pub fn stats(&self) -> &TrialStats {
        &self.stats
    }

    /// The device's time stamp and calibrated forces of `s`, when it has
    /// them, each on its own channel (registered on first use: sources
    /// without them add no channel).
    fn log_device_extras(&mut self, s: &TactileSample, seq: u32) -> Result<(), ObserverError> {
        if let Some(msg) = TactileDeviceTime::new(s) {
            let ch = registered(&self.logger, &mut self.ch.device_time)?;
            self.logger.log_json(ch, s.t, s.t, seq, &msg)?;
        }
        if let Some(msg) =
            TactileCalibrated::new(s, &self.layout).filter(|_| self.force_calibration.is_none())
        {
            let ch = registered(&self.logger, &mut self.ch.calibrated)?;
            self.logger.log_json(ch, s.t, s.t, seq, &msg)?;
        }
        if let Some(msg) = TactileReference::new(s, &self.layout) {
            let ch = registered(&self.logger, &mut self.ch.reference)?;
            self.logger.log_json(ch, s.t, s.t, seq, &msg)?;
        }
        Ok(())
    }

    fn log<T: ChannelMessage>(&self, ch: &ChannelHandle<T>, t: TimeNs, msg: &T) -> Result<(), ObserverError> {
        self.logger.log_json(ch, t, t, 0, msg)?;
        Ok(())
    }

    /// The protocol's channels; an error when the observer records without them.
    fn control(&self) -> Result<&ControlChannels, ObserverError> {
        self.ch.control.as_ref().ok_or_else(|| "this recording has no control channels".into())
    }
}

impl TrialObserver for SessionObserver<'_> {
    /// Records a status the hand reported, on `/hand/state`.
    fn on_hand_status(&mut self, status: &HandStatus) -> Result<(), ObserverError> {
        let ch = registered(&self.logger, &mut self.ch.hand_state)?;
        self.logger.log_json(ch, status.t, status.t, 0, &HandState::new(status))?;
        if let Some(x) = self.extension.as_mut() {
            x.on_hand_status(status);
        }
        Ok(())
    }

    fn on_tactile(&mut self, s: &TactileSample) -> Result<(), ObserverError> {
        self.stats.scans += 1;
        self.last_sequence = s.sequence;
        let seq = (s.sequence & u64::from(u32::MAX)) as u32;
        self.logger.log_json(&self.ch.raw, s.t, s.t, seq, &TactileRaw::new(s, &self.layout))?;
        self.log_device_extras(s, seq)?;
        (self.progress)(s.t);
        Ok(())
    }

    fn on_truth(&mut self, t: &SimTruth) -> Result<(), ObserverError> {
        self.stats.truth.push((t.t, t.position_m, t.velocity_mps));
        if let Some(x) = self.extension.as_mut() {
            x.on_truth(t);
        }
        let Some(ch) = &self.ch.truth else { return Ok(()) };
        let msg = TruthMsg {
            position: t.position_m,
            velocity: t.velocity_mps,
            sliding: t.sliding(),
            supported: t.supported,
            normal_force: PerFinger::from_array(t.normal_n),
            friction_force: PerFinger::from_array(t.friction_n),
        };
        self.log(ch, t.t, &msg)
    }

    fn on_tare(&mut self, t: TimeNs, tare: &Tare) -> Result<(), ObserverError> {
        let msg = TactileTare { samples: tare.scans, baseline: sensor_taxels(&self.layout, &tare.baseline) };
        self.log(&self.control()?.tare, t, &msg)
    }

    fn on_zeroed(&mut self, t: TimeNs, zeroed: &Baseline) -> Result<(), ObserverError> {
        self.log(
            &self.control()?.zeroed,
            t,
            &TactileZeroed { sensors: sensor_taxels(&self.layout, zeroed) },
        )?;
        if let Some(cal) = &self.force_calibration {
            let forces = cal.forces_n(zeroed);
            let msg = TactileCalibrated {
                sequence: self.last_sequence,
                sensors: sensor_taxels(&self.layout, &forces),
            };
            let seq = (self.last_sequence & u64::from(u32::MAX)) as u32;
            let ch = registered(&self.logger, &mut self.ch.calibrated)?;
            self.logger.log_json(ch, t, t, seq, &msg)?;
        }
        match self.extension.as_mut() {
            Some(x) => x.on_zeroed(t, zeroed),
            None => Ok(()),
        }
    }

    fn on_control(&mut self, t: TimeNs, r: &ControlRecord) -> Result<(), ObserverError> {
        let fingers = PerFinger::from_fn(|f| FingerSetpoint {
            desired: r.desired_counts[f.index()],
            achieved: r.achieved_counts[f.index()],
        });
        let msg = GraspControl { phase: r.phase, reference: r.reference_counts, fingers };
        self.log(&self.control()?.grasp, t, &msg)
    }

    fn on_command(
        &mut self,
        t: TimeNs,
        command: &ActuatorCommand,
        limited: bool,
    ) -> Result<(), ObserverError> {
        let control = self.ch.control.as_mut().ok_or("a recording-only observer got a hand command")?;
        match command {
            ActuatorCommand::FingerVolts(volts) => {
                let ch = registered(&self.logger, &mut control.command)?;
                let msg = HandCommand { volts: PerFinger::from_array(*volts), saturated: limited };
                self.logger.log_json(ch, t, t, 0, &msg)?;
            }
            ActuatorCommand::Gripper(r) => {
                let ch = registered(&self.logger, &mut control.gripper)?;
                let msg = GripperCommand {
                    position: r.position_steps,
                    speed: r.speed,
                    force: r.force,
                    clamped: limited,
                };
                self.logger.log_json(ch, t, t, 0, &msg)?;
            }
        }
        Ok(())
    }

    fn on_frame(&mut self, mut frame: Frame) -> Result<Option<f64>, ObserverError> {
        self.stats.frames += 1;
        let seq = (frame.sequence & u64::from(u32::MAX)) as u32;
        let detection = match self.marker.as_mut() {
            Some(m) => m.detect(&frame)?,
            None => ArucoDetection::missed(),
        };
        if detection.detected {
            self.stats.detections += 1;
        }
        if let Some(p) = detection.position_on_axis_m {
            self.stats.max_marker_travel_m = self.stats.max_marker_travel_m.max(p.abs());
        }
        let mut pending = None;
        if let Some(ch) = &self.ch.image {
            match (&frame.encoded, &self.image_encoder, &frame.pixels) {
                (Some(encoded), ..) => {
                    let msg = CompressedImage::new(frame.t, "camera", encoded);
                    self.logger.log_json_lossy(ch, frame.t, frame.t, seq, &msg)?;
                }
                (None, Some(encoder), Some(_)) => {
                    pending = Some((encoder, self.logger.log_json_pending(ch, frame.t, frame.t, seq)?));
                }
                _ => {}
            }
        }
        if let Some(ch) = &self.ch.aruco {
            self.logger.log_json(ch, frame.t, frame.t, seq, &detection)?;
        }
        if let Some(x) = self.extension.as_mut() {
            x.on_frame(&frame, detection.position_on_axis_m)?;
        }
        if let (Some((encoder, out)), Some(pixels)) = (pending, frame.pixels.take()) {
            encoder.submit(pixels, frame.t, out);
        }
        Ok(detection.position_on_axis_m)
    }

    fn on_event(&mut self, t: TimeNs, e: &ProtocolEvent) -> Result<(), ObserverError> {
        if e.phase == slidetrack_core::Phase::Release {
            self.stats.release_at = Some(t);
        }
        if matches!(e.phase, slidetrack_core::Phase::Done | slidetrack_core::Phase::Aborted) {
            let last = self.decoder_written.map_or(t, |(w, _)| w.max(t));
            self.flush_decoder(last)?;
        }
        if let Some(x) = self.extension.as_mut() {
            x.on_event(t, e);
        }
        tracing::info!(phase = e.phase.name(), "{}", e.message);
        let msg = EventMsg { phase: e.phase, message: e.message.clone(), abort: e.abort.is_some() };
        self.log(&self.ch.events, t, &msg)
    }

    fn on_decoder(&mut self, t: TimeNs, counters: &DecoderCounters) -> Result<(), ObserverError> {
        registered(&self.logger, &mut self.ch.decoder)?;
        self.stats.decoder = Some(*counters);
        let due = match self.decoder_written {
            None => true,
            Some((t0, c0)) => counters.errors_differ(&c0) || t.secs_since(t0) >= DECODER_LOG_PERIOD_S,
        };
        if due { self.flush_decoder(t) } else { Ok(()) }
    }
}
