//! One trial on a rig (simulated, real or replayed), recorded to one session file.

use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;
use std::time::{Instant, SystemTime};

use anyhow::{Context, Result};
use slidetrack_calibration::tactile_force::TactileForceCalibration;
use slidetrack_control::{AbortReason, TrialOutcome, run_trial};
use slidetrack_core::{DeviceError, TactileInfo, TimeNs};
use slidetrack_session::{Logger, Recorder, RecorderOptions, SessionMetadata, TAXEL_LAYOUT_KEY, TaxelLayout};
use slidetrack_sim::sliding_episodes;

use crate::observer::{SessionObserver, TrialExtension, TrialStats};
use crate::rig::{RigKind, RigSetup, TrialSpec, build_rig, protocol_for};
use crate::vision::shared_camera::{start_recording, stop_recording};

/// How a trial went.
pub struct TrialReport {
    /// The session file.
    pub path: PathBuf,
    /// How the protocol ended.
    pub outcome: TrialOutcome,
    /// What was recorded.
    pub stats: TrialStats,
    /// Wall time the trial took (s).
    pub wall_s: f64,
    /// Images the recorder had to drop.
    pub images_dropped: u64,
}

impl TrialReport {
    /// The device error that aborted the trial, if one did.
    pub fn device_error(&self) -> Option<&DeviceError> {
        match &self.outcome.abort {
            Some(AbortReason::Device(e)) => Some(e),
            _ => None,
        }
    }

    /// Sliding episodes and travel (m) of the simulator's truth before the release.
    pub fn sliding_summary(&self) -> (usize, f64) {
        let end = self.stats.release_at.unwrap_or(TimeNs(u64::MAX));
        let track: Vec<_> = self
            .stats
            .truth
            .iter()
            .filter(|(t, ..)| *t < end)
            .map(|&(t, p, v)| (t.as_secs_f64(), p, v))
            .collect();
        let travel = track.last().map_or(0.0, |x| x.1);
        (sliding_episodes(&track, 1e-3, 0.5, 5e-4).len(), travel)
    }

    /// One line for humans.
    pub fn summary_line(&self) -> String {
        let (episodes, travel) = self.sliding_summary();
        let status = match &self.outcome.abort {
            None if self.outcome.completed => "complete".to_string(),
            None => "incomplete".to_string(),
            Some(reason) => format!("ABORTED: {reason}"),
        };
        let camera = if self.stats.frames > 0 {
            format!(", marker in {}/{} frames", self.stats.detections, self.stats.frames)
        } else {
            String::new()
        };
        format!(
            "{}: {status}; {:.1} s, {} scans{camera}; {episodes} sliding episodes, travel {:.1} cm",
            self.path.display(),
            self.outcome.end.as_secs_f64(),
            self.stats.scans,
            travel * 100.0
        )
    }
}

/// The file name of a trial: `<object>-s<seed>-t<trial>.mcap`.
pub fn session_file_name(object: &str, seed: u64, trial: u32) -> String {
    format!("{object}-s{seed}-t{trial:03}.mcap")
}

fn rfc3339_now() -> String {
    humantime::format_rfc3339_seconds(SystemTime::now()).to_string()
}

/// Key of the session metadata holding the duration of the sliding cycles
/// (s), which a replay needs to run the protocol as it ran.
pub const CYCLES_DURATION_KEY: &str = "cycles_duration_s";

/// Runs one trial of the simulated rig and records it to `spec.path`.
pub fn run_sim_trial(
    spec: &TrialSpec,
    stop: &AtomicBool,
    progress: &mut dyn FnMut(TimeNs),
) -> Result<TrialReport> {
    record_trial(build_rig(RigKind::Sim, spec)?, spec, stop, progress)
}

/// Runs the controlled-sliding protocol on a rig and records everything to
/// `spec.path`. `progress` receives the session time of every scan; `stop`
/// ends the trial early with a safe release. The file is finished (complete
/// and readable) on every path out, including errors of the trial.
pub fn record_trial(
    setup: RigSetup,
    spec: &TrialSpec,
    stop: &AtomicBool,
    progress: &mut dyn FnMut(TimeNs),
) -> Result<TrialReport> {
    record_trial_with(setup, spec, stop, progress, None)
}

/// Makes the live extension of a trial from the trial's logger (it registers
/// its own channels there).
pub type ExtensionFactory<'a> =
    Box<dyn FnOnce(&Logger, &TactileInfo) -> Result<Box<dyn TrialExtension + 'a>> + 'a>;

/// [`record_trial`] with a live extension (the trackers of `track`).
pub fn record_trial_with<'a>(
    setup: RigSetup,
    spec: &TrialSpec,
    stop: &AtomicBool,
    progress: &'a mut dyn FnMut(TimeNs),
    extension: Option<ExtensionFactory<'a>>,
) -> Result<TrialReport> {
    let started = Instant::now();
    let RigSetup {
        mut rig, tactile_info, markers, rig_name, extra_metadata, mut rgbd, image_encoder, ..
    } = setup;
    let object = spec.object;
    let metadata = SessionMetadata {
        software_version: env!("CARGO_PKG_VERSION").into(),
        rig: rig_name,
        rig_config: toml::to_string(spec.rig).context("cannot serialise the rig configuration")?,
        object: object.name.clone(),
        object_config: toml::to_string(object).context("cannot serialise the object")?,
        trial: spec.trial.to_string(),
        seed: spec.seed,
        started_at: rfc3339_now(),
    };
    let options =
        RecorderOptions { overwrite: spec.overwrite, live: spec.live.clone(), ..RecorderOptions::default() };
    let mut metadata = metadata.to_map();
    metadata.insert(CYCLES_DURATION_KEY.into(), spec.duration_s.to_string());
    metadata.insert(TAXEL_LAYOUT_KEY.into(), TaxelLayout::new(&tactile_info).to_json());
    metadata.extend(extra_metadata);
    let force_calibration = force_calibration(spec, &tactile_info)?;
    let recorder = Recorder::create_with_options(&spec.path, metadata, options)?;
    start_recording(rgbd.as_mut(), &recorder.logger())?;
    let with_truth = rig.truth.is_some();
    let mut observer =
        SessionObserver::new(recorder.logger(), &tactile_info, markers, with_truth, Box::new(progress))?;
    observer = observer.with_image_encoder(image_encoder)?;
    if let Some(calibration) = force_calibration {
        observer = observer.with_force_calibration(calibration)?;
    }
    if let Some(make) = extension {
        observer = observer.with_extension(make(&recorder.logger(), &tactile_info)?);
    }
    let fingers = tactile_info.finger_map().context("the tactile source's layout")?;
    let mut protocol = protocol_for(spec.rig, object, spec.duration_s, fingers, &rig.hand.spec());
    let outcome = run_trial(&mut rig, &mut protocol, &mut observer, stop);
    let stats = observer.stats().clone();
    // The extension's vision tracker first (it reads the camera's pairs), then the camera.
    drop(observer);
    stop_recording(rgbd);
    let images_dropped = recorder.logger().images_dropped();
    let reason = outcome.abort.as_ref().map(|a| a.to_string());
    recorder
        .finish_with_outcome(outcome.completed, reason)
        .with_context(|| format!("cannot finish {}", spec.path.display()))?;
    Ok(TrialReport {
        path: spec.path.clone(),
        outcome,
        stats,
        wall_s: started.elapsed().as_secs_f64(),
        images_dropped,
    })
}

/// The rig's tactile force calibration, checked against its tactile
/// sensors before anything is recorded.
fn force_calibration(spec: &TrialSpec, tactile: &TactileInfo) -> Result<Option<TactileForceCalibration>> {
    let Some(path) = &spec.rig.tactile_calibration else { return Ok(None) };
    let calibration = crate::tactile_force::apply::load_calibration(path)?;
    calibration
        .check_layout(&tactile.layout)
        .with_context(|| format!("tactile_calibration {}", path.display()))?;
    Ok(Some(calibration))
}

/// Makes `dir` (and parents) and checks that a file can be written in it.
pub fn prepare_out_dir(dir: &Path) -> Result<()> {
    std::fs::create_dir_all(dir)
        .with_context(|| format!("cannot create output directory {}", dir.display()))?;
    let probe = dir.join(".slidetrack-write-test");
    std::fs::write(&probe, b"")
        .with_context(|| format!("output directory {} is not writable", dir.display()))?;
    let _ = std::fs::remove_file(probe);
    Ok(())
}
