//! Recording a rig's devices without running the controlled-sliding protocol
//! (`slidetrack record`): for bring-up, and for trials that something else
//! drives (teleoperation, another controller), the way the real XELA
//! recordings in `shared/testdata` were made.
//!
//! The tactile source paces the recording, as it paces a trial: each scan is
//! recorded on `/tactile/raw` (with the decoder's counters of real devices),
//! then the simulator's truth (simulated rig), the hand's state when the hand
//! can report it without being commanded (`/hand/state`), and every camera
//! frame that arrived, with its marker detection. The hand actuator is never
//! opened ([`HandUse::Watch`]). A device error or the end of the duration ends
//! the recording; the file is finished (complete and readable) on every path.

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use anyhow::{Context, Result};
use slidetrack_control::{AbortReason, ProtocolEvent, TrialObserver};
use slidetrack_core::{DeviceError, HandMonitor, Phase, TactileInfo, TimeNs};
use slidetrack_session::{Recorder, RecorderOptions, SessionMetadata, TAXEL_LAYOUT_KEY, TaxelLayout};

use crate::observer::{SessionObserver, TrialStats};
use crate::rig::{RigSetup, TrialSpec};
use crate::vision::shared_camera::{start_recording, stop_recording};

/// Key of the session metadata that marks a recording made by `slidetrack
/// record` (value: `record`), which has no protocol channels.
pub const RECORDING_KIND_KEY: &str = "recording";

/// How a recording ended.
#[derive(Clone, Debug, PartialEq)]
pub enum RecordEnd {
    /// The requested duration was reached.
    Duration,
    /// Stopped by the user (Ctrl-C).
    Interrupted,
    /// A device failed; what was recorded until then is in the file.
    Device(DeviceError),
    /// The recorder failed.
    Recording(String),
}

/// What a recording did.
#[derive(Clone, Debug)]
pub struct RecordReport {
    /// The session file.
    pub path: std::path::PathBuf,
    /// Why it ended.
    pub end: RecordEnd,
    /// Session time of the last scan.
    pub last_scan: TimeNs,
    /// What was recorded.
    pub stats: TrialStats,
    /// Statuses recorded on `/hand/state`.
    pub hand_states: u64,
    /// Wall time the recording took (s).
    pub wall_s: f64,
}

impl RecordReport {
    /// One line for humans.
    pub fn summary_line(&self) -> String {
        let end = match &self.end {
            RecordEnd::Duration => "complete".to_string(),
            RecordEnd::Interrupted => "interrupted".to_string(),
            RecordEnd::Device(e) => format!("STOPPED: {e}"),
            RecordEnd::Recording(e) => format!("STOPPED: recording failed: {e}"),
        };
        let camera = if self.stats.frames > 0 {
            format!(", {} camera frames (marker in {})", self.stats.frames, self.stats.detections)
        } else {
            String::new()
        };
        let hand =
            if self.hand_states > 0 { format!(", {} hand states", self.hand_states) } else { String::new() };
        format!(
            "{}: {end}; {:.1} s, {} scans{camera}{hand}",
            self.path.display(),
            self.last_scan.as_secs_f64(),
            self.stats.scans
        )
    }
}

/// The metadata record of a `record` session.
fn record_metadata(
    spec: &TrialSpec,
    rig_name: String,
    tactile_info: &TactileInfo,
    extra_metadata: BTreeMap<String, String>,
) -> Result<BTreeMap<String, String>> {
    let metadata = SessionMetadata {
        software_version: env!("CARGO_PKG_VERSION").into(),
        rig: rig_name,
        rig_config: toml::to_string(spec.rig).context("cannot serialise the rig configuration")?,
        object: spec.object.name.clone(),
        object_config: toml::to_string(spec.object).context("cannot serialise the object")?,
        trial: spec.trial.to_string(),
        seed: spec.seed,
        started_at: humantime::format_rfc3339_seconds(std::time::SystemTime::now()).to_string(),
    };
    let mut metadata = metadata.to_map();
    metadata.insert(TAXEL_LAYOUT_KEY.into(), TaxelLayout::new(tactile_info).to_json());
    metadata.insert(RECORDING_KIND_KEY.into(), "record".into());
    metadata.extend(extra_metadata);
    Ok(metadata)
}

/// Records the devices of `setup` into `spec.path` for `duration_s` seconds
/// of session time (until `stop` when `None`). `progress` receives the
/// session time of every scan.
pub fn record_devices(
    setup: RigSetup,
    spec: &TrialSpec,
    duration_s: Option<f64>,
    stop: &AtomicBool,
    progress: &mut dyn FnMut(TimeNs),
) -> Result<RecordReport> {
    let started = Instant::now();
    let RigSetup {
        mut rig, tactile_info, markers, rig_name, extra_metadata, mut rgbd, image_encoder, ..
    } = setup;
    let mut hand_monitor = rig.hand_monitor.take();
    let metadata = record_metadata(spec, rig_name, &tactile_info, extra_metadata)?;
    let options =
        RecorderOptions { overwrite: spec.overwrite, live: spec.live.clone(), ..RecorderOptions::default() };
    let recorder = Recorder::create_with_options(&spec.path, metadata, options)?;
    start_recording(rgbd.as_mut(), &recorder.logger())?;
    let with_truth = rig.truth.is_some();
    let mut observer = SessionObserver::recording(
        recorder.logger(),
        &tactile_info,
        markers,
        with_truth,
        Box::new(progress),
    )?
    .with_image_encoder(image_encoder)?;
    let end_at = duration_s.map(TimeNs::from_secs_f64);
    let mut hand_states = 0;
    let mut last_scan = rig.clock.now();
    let end = loop {
        if stop.load(Ordering::Relaxed) {
            break RecordEnd::Interrupted;
        }
        let sample = match rig.tactile.read() {
            Ok(s) => s,
            Err(e) => {
                if let Some(counters) = rig.tactile.counters() {
                    let _ = observer.on_decoder(last_scan, &counters);
                }
                break RecordEnd::Device(e);
            }
        };
        if end_at.is_some_and(|end| sample.t > end) {
            break RecordEnd::Duration;
        }
        last_scan = sample.t;
        match record_scan(&mut rig, hand_monitor.as_deref_mut(), &mut observer, &sample) {
            Ok(states) => hand_states += states,
            Err(ScanError::Device(e)) => break RecordEnd::Device(e),
            Err(ScanError::Recording(e)) => break RecordEnd::Recording(e),
        }
    };
    let (phase, message, abort) = match &end {
        RecordEnd::Duration => (Phase::Done, "recording complete".to_string(), None),
        RecordEnd::Interrupted => {
            (Phase::Aborted, "recording interrupted".to_string(), Some(AbortReason::Interrupted))
        }
        RecordEnd::Device(e) => {
            (Phase::Aborted, format!("device error: {e}"), Some(AbortReason::Device(e.clone())))
        }
        RecordEnd::Recording(e) => {
            (Phase::Aborted, format!("recording error: {e}"), Some(AbortReason::Recording(e.clone())))
        }
    };
    // The end event is the last record; a recorder failing here has failed before.
    let _ = observer.on_event(last_scan, &ProtocolEvent { phase, message, abort: abort.clone() });
    let stats = observer.stats().clone();
    drop(observer);
    stop_recording(rgbd);
    recorder
        .finish_with_outcome(end == RecordEnd::Duration, abort.map(|a| a.to_string()))
        .with_context(|| format!("cannot finish {}", spec.path.display()))?;
    Ok(RecordReport {
        path: spec.path.clone(),
        end,
        last_scan,
        stats,
        hand_states,
        wall_s: started.elapsed().as_secs_f64(),
    })
}

/// Why recording a scan's data stopped.
enum ScanError {
    Device(DeviceError),
    Recording(String),
}

/// Records one scan and what came with it; returns the hand states recorded.
fn record_scan(
    rig: &mut slidetrack_control::Rig,
    hand: Option<&mut (dyn HandMonitor + 'static)>,
    observer: &mut SessionObserver,
    sample: &slidetrack_core::TactileSample,
) -> Result<u64, ScanError> {
    let recording = |e: Box<dyn std::error::Error + Send + Sync>| ScanError::Recording(e.to_string());
    observer.on_tactile(sample).map_err(recording)?;
    if let Some(counters) = rig.tactile.counters() {
        observer.on_decoder(sample.t, &counters).map_err(recording)?;
    }
    if let Some(truth) = rig.truth.as_mut().and_then(|s| s.latest()) {
        observer.on_truth(&truth).map_err(recording)?;
    }
    let mut states = 0;
    if let Some(hand) = hand
        && let Some(status) = hand.status().map_err(ScanError::Device)?
    {
        observer.on_hand_status(&status).map_err(recording)?;
        states += 1;
    }
    if let Some(camera) = rig.camera.as_mut() {
        while let Some(frame) = camera.poll().map_err(ScanError::Device)? {
            observer.on_frame(frame).map_err(recording)?;
        }
    }
    Ok(states)
}
