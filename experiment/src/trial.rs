//! One trial on the simulated rig, recorded to one session file.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use std::time::{Instant, SystemTime};

use anyhow::{Context, Result, bail};
use slidetrack_calibration::{Dictionary, MarkerTracker, SlidingAxis, encode_jpeg, marker_pattern};
use slidetrack_control::{GraspProfile, Protocol, ProtocolConfig, Rig, TrialOutcome, run_trial};
use slidetrack_core::{
    Camera, CameraIntrinsics, Clock, SimClock, TactileInfo, TactileSource, TimeNs, WallClock,
};
use slidetrack_session::{Logger, Recorder, RecorderOptions, SessionMetadata};
use slidetrack_sim::camera::SimCameraRenderer;
use slidetrack_sim::{ObjectConfig, SimCamera, SimDevices, Stream, sliding_episodes, stream_seed};

use crate::observer::{MarkerTracking, SessionObserver, TrialExtension, TrialStats};
use crate::rig_config::RigConfig;

/// Which rig runs a trial.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RigKind {
    /// The simulated rig (physics model of the hand, object and sensors).
    Sim,
    /// The real rig, with the devices of the rig configuration's `[hw]` table.
    Hw,
}

/// What to run.
pub struct TrialSpec<'a> {
    /// The rig.
    pub rig: &'a RigConfig,
    /// The object.
    pub object: &'a ObjectConfig,
    /// Seed of the simulated rig.
    pub seed: u64,
    /// Trial number.
    pub trial: u32,
    /// Duration of the sliding cycles (s).
    pub duration_s: f64,
    /// Render, detect and record the camera.
    pub camera: bool,
    /// Run on wall-clock time.
    pub realtime: bool,
    /// Replace an existing session file.
    pub overwrite: bool,
    /// Session file to write.
    pub path: PathBuf,
}

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

/// A rig ready to run, with what the recorder needs to know about it.
pub struct RigSetup {
    /// The devices.
    pub rig: Rig,
    /// Facts about the tactile source, for the taxel layout.
    pub tactile_info: TactileInfo,
    /// Marker detection on the camera's frames, when there is a camera.
    pub tracking: Option<MarkerTracking>,
    /// `sim`, or the name of the real rig.
    pub rig_name: String,
}

/// The simulated rig of `spec`'s trial, with its camera when asked for.
pub fn build_sim_rig(spec: &TrialSpec) -> Result<RigSetup> {
    let clock: Arc<dyn Clock> =
        if spec.realtime { Arc::new(WallClock::start()) } else { Arc::new(SimClock::new()) };
    let object = spec.object;
    let sim = SimDevices::new(&spec.rig.sim, object, spec.seed, spec.trial, clock.clone());
    let tactile_info = sim.tactile.info();
    let geometry = &spec.rig.geometry;
    let (camera, tracking) = if spec.camera {
        let marker = marker_pattern(&spec.rig.marker.dictionary, spec.rig.marker.id)
            .context("cannot make the marker for the simulated camera")?;
        let seed = stream_seed(spec.seed, spec.trial, Stream::Camera);
        let renderer =
            SimCameraRenderer::new(spec.rig.camera.clone(), object.appearance.clone(), marker, seed)
                .context("cannot set up the simulated camera")?;
        let camera = SimCamera::new(
            sim.world.clone(),
            renderer,
            geometry.object_start_in_hand_m,
            geometry.sliding_axis_in_hand,
        )?;
        // libjpeg-turbo through OpenCV: several times faster than the built-in encoder.
        let quality = camera.jpeg_quality();
        let camera = camera.with_encoder(Box::new(move |image| match encode_jpeg(image, quality) {
            Ok(encoded) => Some(encoded),
            Err(e) => {
                tracing::warn!("sim camera: {e}");
                None
            }
        }));
        let tracking = marker_tracking(spec, camera.hand_from_camera(), camera.intrinsics())?;
        (Some(Box::new(camera) as Box<dyn Camera>), Some(tracking))
    } else {
        (None, None)
    };
    let rig = Rig {
        tactile: Box::new(sim.tactile),
        hand: Box::new(sim.hand),
        camera,
        clock,
        truth: Some(Box::new(sim.truth)),
    };
    Ok(RigSetup { rig, tactile_info, tracking, rig_name: "sim".into() })
}

/// Marker detection for a camera at `hand_from_camera` with `intrinsics`.
pub fn marker_tracking(
    spec: &TrialSpec,
    hand_from_camera: nalgebra::Isometry3<f64>,
    intrinsics: &CameraIntrinsics,
) -> Result<MarkerTracking> {
    let axis = SlidingAxis::new(hand_from_camera, spec.rig.geometry.sliding_axis_in_hand.into())?;
    Ok(MarkerTracking {
        tracker: MarkerTracker::new(Dictionary::from_name(&spec.rig.marker.dictionary)?, spec.rig.marker.id)?,
        marker_size_m: spec.object.appearance.marker_size_m,
        intrinsics: intrinsics.clone(),
        projector: axis.projector(),
    })
}

/// The rig of `spec`, simulated or real, once it is clear that its session
/// file may be written.
pub fn build_rig(kind: RigKind, spec: &TrialSpec) -> Result<RigSetup> {
    if spec.path.exists() && !spec.overwrite {
        bail!("session file {} already exists; pass --overwrite to replace it", spec.path.display());
    }
    match kind {
        RigKind::Sim => build_sim_rig(spec),
        #[cfg(all(feature = "devices", target_os = "linux"))]
        RigKind::Hw => crate::hw_rig::build_hw_rig(spec),
        #[cfg(not(all(feature = "devices", target_os = "linux")))]
        RigKind::Hw => bail!(
            "--rig hw needs the real devices' backends, and this slidetrack was built without them \
             (the `devices` feature, Linux only)"
        ),
    }
}

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
pub type ExtensionFactory<'a> = Box<dyn FnOnce(&Logger) -> Result<Box<dyn TrialExtension + 'a>> + 'a>;

/// [`record_trial`] with a live extension (the trackers of `track`).
pub fn record_trial_with<'a>(
    setup: RigSetup,
    spec: &TrialSpec,
    stop: &AtomicBool,
    progress: &'a mut dyn FnMut(TimeNs),
    extension: Option<ExtensionFactory<'a>>,
) -> Result<TrialReport> {
    let started = Instant::now();
    let RigSetup { mut rig, tactile_info, tracking, rig_name } = setup;
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
    let options = RecorderOptions { overwrite: spec.overwrite, ..RecorderOptions::default() };
    let recorder = Recorder::create_with_options(&spec.path, metadata.to_map(), options)?;
    let with_truth = rig.truth.is_some();
    let mut observer =
        SessionObserver::new(recorder.logger(), &tactile_info, tracking, with_truth, Box::new(progress))?;
    if let Some(make) = extension {
        observer = observer.with_extension(make(&recorder.logger())?);
    }
    let e = &object.experiment;
    let mut protocol = Protocol::new(ProtocolConfig {
        settings: spec.rig.protocol.clone(),
        profile: GraspProfile {
            max_counts: e.grasp_max_counts,
            min_counts: e.grasp_min_counts,
            period_s: e.period_s,
            sharpness: e.sharpness,
        },
        travel_limit_m: e.travel_limit_m,
        cycles_duration_s: spec.duration_s,
    });
    let outcome = run_trial(&mut rig, &mut protocol, &mut observer, stop);
    let stats = observer.stats().clone();
    drop(observer);
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
