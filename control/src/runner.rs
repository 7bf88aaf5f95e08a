//! The trial loop: the same code drives the simulated and the real rig.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use slidetrack_core::{
    ActuatorCommand, Camera, Clock, DecoderCounters, DeviceError, Frame, HandActuator, HandMonitor,
    HandStatus, Phase, SimTruth, TactileSample, TactileSource, TimeNs, TruthSource,
};

use crate::protocol::{Baseline, ControlRecord, HandAction, Protocol, ProtocolEvent, Tare};
use crate::safety::AbortReason;

/// The devices of one rig.
pub struct Rig {
    /// Tactile modules of the three fingertips.
    pub tactile: Box<dyn TactileSource>,
    /// The hand.
    pub hand: Box<dyn HandActuator>,
    /// The camera that sees the marker, if any.
    pub camera: Option<Box<dyn Camera>>,
    /// The session clock the devices share.
    pub clock: Arc<dyn Clock>,
    /// The simulator's truth, on the simulated rig.
    pub truth: Option<Box<dyn TruthSource>>,
    /// Reads the hand's own status (a gripper's registers, the fingers'
    /// travel), when the hand can tell.
    pub hand_monitor: Option<Box<dyn HandMonitor>>,
}

/// A failure of a consumer of the trial's data (the recorder, a detector).
pub type ObserverError = Box<dyn std::error::Error + Send + Sync>;

/// Receives everything a trial produces, in time order. A returned error
/// aborts the trial with a safe release.
pub trait TrialObserver {
    /// A raw tactile scan.
    fn on_tactile(&mut self, sample: &TactileSample) -> Result<(), ObserverError>;
    /// The simulator's truth at that scan.
    fn on_truth(&mut self, truth: &SimTruth) -> Result<(), ObserverError>;
    /// A new tactile baseline.
    fn on_tare(&mut self, t: TimeNs, tare: &Tare) -> Result<(), ObserverError>;
    /// Baseline-subtracted channels (counts).
    fn on_zeroed(&mut self, t: TimeNs, zeroed: &Baseline) -> Result<(), ObserverError>;
    /// A control tick.
    fn on_control(&mut self, t: TimeNs, record: &ControlRecord) -> Result<(), ObserverError>;
    /// A command sent to the hand, as the hand executes it (saturated or
    /// clamped to its range), and whether that limited it.
    fn on_command(
        &mut self,
        t: TimeNs,
        command: &ActuatorCommand,
        limited: bool,
    ) -> Result<(), ObserverError>;
    /// A camera frame; returns the marker travel along the sliding axis (m)
    /// when the marker was seen.
    fn on_frame(&mut self, frame: Frame) -> Result<Option<f64>, ObserverError>;
    /// A phase change or an abort.
    fn on_event(&mut self, t: TimeNs, event: &ProtocolEvent) -> Result<(), ObserverError>;
    /// A status the hand reported about itself (after each scan, when there
    /// is a new one).
    fn on_hand_status(&mut self, _status: &HandStatus) -> Result<(), ObserverError> {
        Ok(())
    }
    /// The tactile decoder's counters after a scan, and once more when the
    /// tactile source fails (sources that decode a stream only).
    fn on_decoder(&mut self, _t: TimeNs, _counters: &DecoderCounters) -> Result<(), ObserverError> {
        Ok(())
    }
}

/// How a trial ended.
#[derive(Clone, Debug, PartialEq)]
pub struct TrialOutcome {
    /// True when every phase ran to its end.
    pub completed: bool,
    /// Why it stopped early.
    pub abort: Option<AbortReason>,
    /// Session time at the end.
    pub end: TimeNs,
    /// Error of the hand's release, if releasing failed too.
    pub release_error: Option<DeviceError>,
}

/// Runs one controlled-sliding trial on `rig` until the protocol finishes,
/// an abort, or `stop` becomes true. The hand is released on every path out.
pub fn run_trial(
    rig: &mut Rig,
    protocol: &mut Protocol,
    observer: &mut dyn TrialObserver,
    stop: &AtomicBool,
) -> TrialOutcome {
    let mut released = false;
    let mut release_error = None;
    let mut last_t = rig.clock.now();
    while !protocol.finished() {
        if stop.load(Ordering::Relaxed) {
            emit(observer, last_t, protocol.abort(AbortReason::Interrupted));
            break;
        }
        let sample = match rig.tactile.read() {
            Ok(s) => s,
            Err(e) => {
                if let Some(counters) = rig.tactile.counters() {
                    // The trial ends with the error below; a recorder failure adds nothing.
                    let _ = observer.on_decoder(last_t, &counters);
                }
                emit(observer, last_t, protocol.device_error(e));
                break;
            }
        };
        last_t = sample.t;
        if let Err(e) = observe_scan(rig, protocol, observer, &sample) {
            emit(observer, last_t, protocol.abort(AbortReason::Recording(e.to_string())));
            break;
        }
        let age_event = protocol.check_data_age(rig.clock.now(), sample.t);
        emit(observer, last_t, age_event);
        if protocol.phase() == Phase::Release && !released {
            released = true;
            release_error = rig.hand.release().err();
        }
    }
    if !released {
        release_error = rig.hand.release().err();
    }
    TrialOutcome {
        completed: protocol.phase() == Phase::Done,
        abort: protocol.abort_reason().cloned(),
        end: last_t,
        release_error,
    }
}

fn emit(observer: &mut dyn TrialObserver, t: TimeNs, event: Option<ProtocolEvent>) {
    if let Some(event) = event {
        // The trial is ending anyway; a recorder that fails here has already
        // reported its failure through the abort that got us here.
        let _ = observer.on_event(t, &event);
    }
}

fn observe_scan(
    rig: &mut Rig,
    protocol: &mut Protocol,
    observer: &mut dyn TrialObserver,
    sample: &TactileSample,
) -> Result<(), ObserverError> {
    let t = sample.t;
    observer.on_tactile(sample)?;
    if let Some(counters) = rig.tactile.counters() {
        observer.on_decoder(t, &counters)?;
    }
    if let Some(truth) = rig.truth.as_mut().and_then(|s| s.latest()) {
        observer.on_truth(&truth)?;
    }
    let out = protocol.on_tactile(sample);
    if let Some(tare) = &out.tare {
        observer.on_tare(t, tare)?;
    }
    if let Some(zeroed) = &out.zeroed {
        observer.on_zeroed(t, zeroed)?;
    }
    if let Some(record) = &out.control {
        observer.on_control(t, record)?;
    }
    for event in &out.events {
        observer.on_event(t, event)?;
    }
    if let Some(HandAction::Command(command)) = out.action {
        if let Err(e) = rig.hand.command(&command) {
            emit(observer, t, protocol.device_error(e));
            return Ok(());
        }
        let (applied, limited) = command.limited_to(&rig.hand.spec()).unwrap_or((command, false));
        observer.on_command(t, &applied, limited)?;
    }
    if let Some(monitor) = rig.hand_monitor.as_mut() {
        match monitor.status() {
            Ok(Some(status)) => observer.on_hand_status(&status)?,
            Ok(None) => {}
            Err(e) => {
                emit(observer, t, protocol.device_error(e));
                return Ok(());
            }
        }
    }
    if let Some(camera) = rig.camera.as_mut() {
        loop {
            match camera.poll() {
                Ok(Some(frame)) => {
                    let travel = observer.on_frame(frame)?;
                    emit(observer, t, protocol.on_marker(travel));
                }
                Ok(None) => break,
                Err(e) => {
                    emit(observer, t, protocol.device_error(e));
                    break;
                }
            }
        }
    }
    Ok(())
}
