//! A tracker online on the rig's RGB-D camera (`vision track --live --rig
//! rig.toml`; `[rgbd]`: V4L2 colour and depth nodes, or a recording standing
//! in for them), until stopped, a duration or the end of a recording. With a
//! session to write, the paired and registered frames (`/rgbd/*`), the
//! estimates (`/estimate/*/<tracker>`) and, on a replayed simulated session,
//! its truth (`/sim/object`) are recorded on the run's clock.

use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};

use anyhow::{Context, Result, bail, ensure};
use slidetrack_core::{CameraIntrinsics, Clock, TimeNs, WallClock};
use slidetrack_estimators::metrics::perturbed_start;
use slidetrack_session::{ReadOptions, Recorder, RecorderOptions};
use slidetrack_vision::eval::{Scored, score};
use slidetrack_vision::input::{CameraPair, PairCounts, RecordedTruth, RgbdSample, RgbdSource};
use slidetrack_vision::live::LiveTracking;
use slidetrack_vision::sources::{
    Arrivals, FrameTruth, MeasurementSource, SessionMeasurements, SlowNetwork, SlowNetworkConfig, TruthSource,
};
use slidetrack_vision::{ObjectModel, PoseReset, TrackerKind, TrackerSettings, VisionError};

use super::camera::{self, LiveCamera, StreamCounts};
use super::input::{InputOptions, check_pose_reset, load_model, own_measurements};
use super::{Measurements, Metadata, SequenceMetrics, TrackerStart};
use crate::rig_config::RigConfig;

/// The options of a live tracking run.
#[derive(Clone)]
pub struct LiveOptions<'a> {
    /// The rig TOML with the `[rgbd]` table.
    pub rig: &'a Path,
    /// The tracker.
    pub kind: TrackerKind,
    /// The model, measurements and start of the tracker.
    pub input_options: InputOptions<'a>,
    /// MaskUKF: start again at a pose measurement this far from the estimate.
    pub pose_reset: Option<PoseReset>,
    /// Stop after this long (s); `None`: when stopped or at the end of a recording.
    pub duration_s: Option<f64>,
    /// Session file for the frames and estimates.
    pub out: Option<&'a Path>,
    /// Replace `out` if it exists.
    pub overwrite: bool,
}

/// A live run with its camera, model, measurements and session open.
pub struct LiveVisionRun {
    kind: TrackerKind,
    init: TrackerStart,
    pose_reset: Option<PoseReset>,
    duration_s: Option<f64>,
    camera: LiveCamera,
    truth: Option<RecordedTruth>,
    /// Session time minus recording time (ns).
    offset_ns: i128,
    model: ObjectModel,
    intrinsics: CameraIntrinsics,
    measurements: Box<dyn MeasurementSource>,
    recorder: Option<Recorder>,
}

/// What a live run did.
pub struct LiveSummary {
    /// Frames processed.
    pub frames: usize,
    /// Frames with an estimate.
    pub tracked: usize,
    /// Wall time of the run (s).
    pub seconds: f64,
    /// Frames per second of the tracker alone.
    pub tracker_fps: f64,
    /// What the camera pair paired and skipped.
    pub pairing: PairCounts,
    /// One line per stream at the end of the run: what it delivered and dropped.
    pub streams: Vec<String>,
    /// What each stream counted, live (the same lines, read again).
    pub stream_counts: StreamCounts,
    /// The errors against a replayed recording's truth.
    pub metrics: Option<SequenceMetrics>,
    /// What the measurement source delivered, when it says.
    pub measurement_summary: Option<String>,
}

impl LiveVisionRun {
    /// Opens the `[rgbd]` camera of `options.rig`, the model, the
    /// measurement source and the session.
    pub fn open(options: &LiveOptions<'_>) -> Result<LiveVisionRun> {
        check_pose_reset(options.pose_reset, options.kind)?;
        let rig_path = options.rig;
        let rig = RigConfig::load(Some(rig_path))?;
        let cfg = rig.rgbd.with_context(|| {
            format!("{}: no [rgbd] table (docs/examples/rgbd-rig.toml shows one)", rig_path.display())
        })?;
        if let Some(d) = options.duration_s {
            ensure!(d.is_finite() && d > 0.0, "--duration must be a positive number of seconds, got {d}");
        }
        let rig_dir = rig_path.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
        let clock: Arc<dyn Clock> = Arc::new(WallClock::start());
        let camera = camera::open(&cfg, rig_dir, Arc::clone(&clock))?;
        let replayed = camera.replay.clone();
        let session = replayed.as_ref().map(|(p, _)| p.as_path());
        let o = &options.input_options;
        let model = load_model(o.model, o.model_scale, session.map(|p| (p, ReadOptions::default())))?;
        let truth = session.map(RecordedTruth::open).transpose()?;
        let offset_ns = replayed.as_ref().map_or(0, |(_, o)| *o);
        let intrinsics = camera.pair.intrinsics().clone();
        let measurements = measurements(o, session, offset_ns, &model, &intrinsics)?;
        let recorder = options.out.map(|path| recorder(options, path, offset_ns, &model)).transpose()?;
        Ok(LiveVisionRun {
            kind: options.kind,
            init: o.init,
            pose_reset: options.pose_reset,
            duration_s: options.duration_s,
            camera,
            truth,
            offset_ns,
            model,
            intrinsics,
            measurements,
            recorder,
        })
    }

    /// Tracks until `stop` is set, the duration passes or the camera ends.
    pub fn run(self, stop: &AtomicBool) -> Result<LiveSummary> {
        let LiveVisionRun { kind, init, pose_reset, duration_s, mut camera, truth, offset_ns, .. } = self;
        let started = Instant::now();
        let until = duration_s.map(|d| started + Duration::from_secs_f64(d));
        let mut frames = WithTruth { camera: &mut camera.pair, truth, offset_ns };
        let mut tracking = None;
        if let Some(first) = frames.next_frame()? {
            let settings = TrackerSettings {
                initial_pose: initial_pose(init, &first)?,
                maskukf_pose_reset: pose_reset,
                ..TrackerSettings::default()
            };
            let mut t = LiveTracking::new(kind, self.model, self.intrinsics, &settings, self.measurements)?;
            if let Some(r) = &self.recorder {
                t = t.recording_to(&r.logger())?;
            }
            t.on_sample(first)?;
            t.run(&mut frames, stop, until)?;
            tracking = Some(t);
        }
        if let Some(r) = self.recorder {
            r.finish()?;
        }
        let tracking = tracking.context("the camera delivered no frame")?;
        let results = tracking.results();
        let first = results.iter().position(|f| f.estimate.is_some()).unwrap_or(results.len());
        let metrics = (first < results.len())
            .then(|| {
                tracking.model().object_points().map(|points| score(results, first, Scored::Tracker, &points))
            })
            .transpose()?;
        let counts = tracking.counts();
        let streams = camera.counts();
        let (pair, stream_counts) = camera.split();
        Ok(LiveSummary {
            frames: counts.frames,
            tracked: counts.tracked,
            seconds: started.elapsed().as_secs_f64(),
            tracker_fps: counts.tracker_fps(),
            pairing: pair.counts(),
            streams,
            stream_counts,
            metrics,
            measurement_summary: tracking.measurement_summary(),
        })
    }
}

/// The camera's frames, each with the truth a replayed session recorded for
/// it (moved onto the run's clock) when there is one.
struct WithTruth<'a> {
    camera: &'a mut CameraPair,
    truth: Option<RecordedTruth>,
    /// Session time minus recording time (ns).
    offset_ns: i128,
}

impl RgbdSource for WithTruth<'_> {
    fn intrinsics(&self) -> &CameraIntrinsics {
        self.camera.intrinsics()
    }

    fn next_frame(&mut self) -> Result<Option<RgbdSample>, VisionError> {
        let Some(mut sample) = self.camera.next_frame()? else { return Ok(None) };
        let Some(truth) = self.truth.as_mut() else { return Ok(Some(sample)) };
        let t = sample.frame.t;
        let recorded =
            u64::try_from(i128::from(t.0) - self.offset_ns).map_err(|_| VisionError::BadValue {
                what: "replayed frame",
                detail: format!("at {} ns, before its recording started", t.0),
            })?;
        let (pose, mask) = truth.at(TimeNs(recorded))?;
        sample.truth = pose.map(|p| slidetrack_core::ObjectTruth { t, ..p });
        sample.truth_mask = mask;
        Ok(Some(sample))
    }
}

/// Where the tracker starts, as `init` says, from the first frame.
fn initial_pose(init: TrackerStart, first: &RgbdSample) -> Result<Option<nalgebra::Isometry3<f64>>> {
    Ok(match init {
        TrackerStart::Measurement => None,
        TrackerStart::Truth | TrackerStart::Perturbed => {
            let truth = first.truth.as_ref().map(|t| t.camera_from_object).context(
                "--init truth|perturbed needs the truth of the first frame: a replayed simulated session",
            )?;
            Some(if init == TrackerStart::Perturbed { perturbed_start(&truth) } else { truth })
        }
    })
}

/// Masks and poses for a live run: the sources that see the frames
/// (`aruco`, `external`) on any camera; a replayed session also brings its
/// own (`/vision/mask`, `/vision/pose`, moved onto the run's clock) and its
/// truth (`network`, `truth`).
fn measurements(
    options: &InputOptions<'_>,
    session: Option<&Path>,
    offset_ns: i128,
    model: &ObjectModel,
    intrinsics: &CameraIntrinsics,
) -> Result<Box<dyn MeasurementSource>> {
    let which = options.measurements;
    Ok(match (which, session) {
        (Measurements::Aruco | Measurements::External, _) => own_measurements(options, model, intrinsics)?,
        (_, None) => bail!(
            "--measurements {} needs a replayed session's masks, poses or truth; a live camera has none \
             (use --measurements aruco or external, or a recording as the [rgbd] camera)",
            format!("{which:?}").to_lowercase()
        ),
        (Measurements::Input, Some(session)) => Box::new(Shifted {
            inner: SessionMeasurements::open(session, ReadOptions::default())?,
            offset_ns,
        }),
        (Measurements::Network, Some(_)) => Box::new(SlowNetwork::new(SlowNetworkConfig::default())),
        (Measurements::Truth, Some(_)) => Box::new(TruthSource { masks: true, poses: true }),
    })
}

/// A recorded source replayed on the run's clock: recording time plus `offset_ns`.
struct Shifted<S> {
    inner: S,
    offset_ns: i128,
}

fn shift(t: TimeNs, by_ns: i128) -> TimeNs {
    TimeNs(u64::try_from(i128::from(t.0) + by_ns).unwrap_or(0))
}

impl<S: MeasurementSource> MeasurementSource for Shifted<S> {
    fn on_frame(&mut self, t: TimeNs, truth: Option<FrameTruth<'_>>) -> Result<Arrivals, VisionError> {
        let mut arrivals = self.inner.on_frame(shift(t, -self.offset_ns), truth)?;
        for m in &mut arrivals.masks {
            (m.frame_t, m.arrival_t) = (shift(m.frame_t, self.offset_ns), shift(m.arrival_t, self.offset_ns));
        }
        for p in &mut arrivals.poses {
            (p.frame_t, p.arrival_t) = (shift(p.frame_t, self.offset_ns), shift(p.arrival_t, self.offset_ns));
        }
        Ok(arrivals)
    }
}

/// The session of a live run, with what produced it in its metadata.
fn recorder(
    options: &LiveOptions<'_>,
    path: &Path,
    offset_ns: i128,
    model: &ObjectModel,
) -> Result<Recorder> {
    let recorder_options = RecorderOptions { overwrite: options.overwrite, ..RecorderOptions::default() };
    let metadata = Metadata::from([
        ("software_version".to_string(), env!("CARGO_PKG_VERSION").to_string()),
        ("tracker".to_string(), options.kind.name().to_string()),
        ("input".to_string(), format!("live: [rgbd] of {}", options.rig.display())),
        ("model".to_string(), model.origin.clone()),
        // Session time minus recording time of a replayed recording (ns).
        ("rgbd_replay_offset_ns".to_string(), offset_ns.to_string()),
    ]);
    Ok(Recorder::create_with_options(path, metadata, recorder_options)?)
}
