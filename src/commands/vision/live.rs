//! `slidetrack vision track --live --rig rig.toml`: a tracker online on the
//! rig's RGB-D camera (`[rgbd]`: V4L2 colour and depth nodes, or a recording
//! standing in for them), until Ctrl-C, `--duration` or the end of a
//! recording. With `--out`, the paired and registered frames (`/rgbd/*`),
//! the estimates (`/estimate/*/<tracker>`) and, on a replayed simulated
//! session, its truth (`/sim/object`) are recorded on the run's clock.

use std::collections::BTreeMap;
use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use anyhow::{Context, Result, bail, ensure};
use serde_json::json;
use slidetrack_core::{Clock, TimeNs, WallClock};
use slidetrack_experiment::rig_config::RigConfig;
use slidetrack_session::{ReadOptions, Recorder, RecorderOptions};
use slidetrack_vision::eval::{Scored, TrackedFrame, score};
use slidetrack_vision::input::{RecordedTruth, RgbdSample, RgbdSource, encode_color_jpeg};
use slidetrack_vision::record::{EstimateChannels, RgbdChannels};
use slidetrack_vision::sources::{
    Arrivals, FrameTruth, MeasurementSource, SessionMeasurements, SlowNetwork, SlowNetworkConfig, TruthSource,
};
use slidetrack_vision::{
    ObjectModel, OnlineTracker, TrackedState, TrackerSettings, VisionError, build_tracker,
};

use super::inputs::{InputOptions, load_model, own_measurements};
use super::live_camera::{self, LiveCamera};
use super::track::external_config;
use crate::cli::{InitArg, MeasurementsArg, VisionTrackArgs as TrackArgs};
use slidetrack_estimators::metrics::perturbed_start;

/// JPEG quality of the recorded colour frames.
const JPEG_QUALITY: i32 = 90;

pub fn run(args: &TrackArgs, quiet: bool) -> Result<()> {
    let rig_path = args.rig.as_deref().context("--live needs --rig rig.toml")?;
    let rig = RigConfig::load(Some(rig_path))?;
    let cfg = rig.rgbd.with_context(|| {
        format!("{}: no [rgbd] table (docs/examples/rgbd-rig.toml shows one)", rig_path.display())
    })?;
    if let Some(d) = args.duration {
        ensure!(d.is_finite() && d > 0.0, "--duration must be a positive number of seconds, got {d}");
    }
    let rig_dir = rig_path.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
    let clock: Arc<dyn Clock> = Arc::new(WallClock::start());
    let mut camera = live_camera::open(&cfg, rig_dir, Arc::clone(&clock))?;
    let replayed = camera.replay.clone();
    let session = replayed.as_ref().map(|(p, _)| p.as_path());
    let model = load_model(&args.model, args.model_scale, session.map(|p| (p, ReadOptions::default())))?;
    let mut truth = session.map(RecordedTruth::open).transpose()?;
    let offset_ns = replayed.as_ref().map_or(0, |(_, o)| *o);
    let intrinsics = camera.pair.intrinsics().clone();
    let mut measurements = measurements(args, session, offset_ns, &model, &intrinsics)?;
    let output = Output::open(args, rig_path, offset_ns, &model, &intrinsics)?;
    if !quiet {
        eprintln!("tracking live on the [rgbd] camera of {} (Ctrl-C stops)", rig_path.display());
    }
    let stop = crate::commands::stop_flag();
    let started = Instant::now();
    let limit = args.duration.map(Duration::from_secs_f64);
    let mut tracker: Option<Box<dyn OnlineTracker>> = None;
    let mut tally = Tally::default();
    while !stop.load(Ordering::SeqCst) && limit.is_none_or(|l| started.elapsed() < l) {
        let Some(mut sample) = camera.pair.next_frame()? else { break };
        if let Some(truth) = truth.as_mut() {
            attach_truth(&mut sample, truth, offset_ns)?;
        }
        let tracker = match &mut tracker {
            Some(t) => t,
            None => tracker.insert(start_tracker(args, &model, &intrinsics, &sample)?),
        };
        let frame_truth = sample.truth.as_ref().zip(sample.truth_mask.as_ref());
        let arrivals = measurements.on_rgbd_frame(
            &sample.frame,
            frame_truth.map(|(t, m)| FrameTruth { camera_from_object: &t.camera_from_object, mask: m }),
        )?;
        let step = Instant::now();
        let state = tracker.process(&sample.frame, &arrivals)?;
        tally.busy += step.elapsed();
        output.log(&sample, state.as_ref())?;
        tally.add(sample, state, &arrivals);
    }
    if let Some(r) = output.recorder {
        r.finish()?;
    }
    let results = &tally.results;
    let first = results.iter().position(|f| f.estimate.is_some()).unwrap_or(results.len());
    let metrics = (first < results.len())
        .then(|| model.object_points().map(|points| score(results, first, Scored::Tracker, &points)))
        .transpose()?;
    let summary = json!({
        "tracker": args.tracker.kind().name(),
        "rig": rig_path,
        "frames": tally.frames,
        "tracked": tally.tracked,
        "seconds": started.elapsed().as_secs_f64(),
        "tracker_fps": if tally.busy.is_zero() { 0.0 } else { tally.frames as f64 / tally.busy.as_secs_f64() },
        "pairing": camera.pair.counts(),
        "streams": camera.counts(),
        "estimates": args.out,
        "metrics": metrics,
    });
    report(args, &summary, &camera);
    if let Some(summary) = measurements.summary() {
        eprintln!("{summary}");
    }
    Ok(())
}

/// What a run counted, and the estimates with the truth when it has one.
#[derive(Default)]
struct Tally {
    frames: usize,
    tracked: usize,
    busy: Duration,
    results: Vec<TrackedFrame>,
    last_pose: Option<nalgebra::Isometry3<f64>>,
}

impl Tally {
    fn add(&mut self, sample: RgbdSample, state: Option<TrackedState>, arrivals: &Arrivals) {
        if let Some(p) = arrivals.latest_pose() {
            self.last_pose = Some(p.value);
        }
        self.frames += 1;
        self.tracked += usize::from(state.is_some());
        if let Some(truth) = sample.truth {
            self.results.push(TrackedFrame {
                truth,
                flow_velocity: state.as_ref().and_then(|s| s.flow_velocity),
                estimate: state.map(|s| s.estimate),
                last_measured_pose: self.last_pose,
            });
        }
    }
}

/// The session of a live run (`--out`) and its channels.
struct Output {
    recorder: Option<Recorder>,
    channels: Option<(RgbdChannels, EstimateChannels)>,
}

impl Output {
    fn open(
        args: &TrackArgs,
        rig: &Path,
        offset_ns: i128,
        model: &ObjectModel,
        intrinsics: &slidetrack_core::CameraIntrinsics,
    ) -> Result<Output> {
        let recorder =
            args.out.as_ref().map(|path| recorder(args, path, rig, offset_ns, model)).transpose()?;
        let channels = match &recorder {
            Some(r) => Some((
                RgbdChannels::register(&r.logger(), intrinsics)?,
                EstimateChannels::register(&r.logger(), args.tracker.kind())?,
            )),
            None => None,
        };
        Ok(Output { recorder, channels })
    }

    /// Records the frame (colour as JPEG), its truth and the estimate.
    fn log(&self, sample: &RgbdSample, state: Option<&TrackedState>) -> Result<()> {
        let (Some(r), Some((rgbd, estimates))) = (&self.recorder, &self.channels) else {
            return Ok(());
        };
        let jpeg = encode_color_jpeg(&sample.frame.color, JPEG_QUALITY)?;
        rgbd.log_frame(&r.logger(), &sample.frame, &jpeg, sample.truth.as_ref(), None)?;
        if let Some(s) = state {
            estimates.log(&r.logger(), s)?;
        }
        Ok(())
    }
}

/// The truth a replayed session recorded for this frame, on the run's clock.
fn attach_truth(sample: &mut RgbdSample, truth: &mut RecordedTruth, offset_ns: i128) -> Result<()> {
    let t = sample.frame.t;
    let recorded = u64::try_from(i128::from(t.0) - offset_ns).context("a frame before its recording")?;
    let (pose, mask) = truth.at(TimeNs(recorded))?;
    sample.truth = pose.map(|p| slidetrack_core::ObjectTruth { t, ..p });
    sample.truth_mask = mask;
    Ok(())
}

/// The tracker, started as `--init` says from the first frame.
fn start_tracker(
    args: &TrackArgs,
    model: &ObjectModel,
    intrinsics: &slidetrack_core::CameraIntrinsics,
    first: &RgbdSample,
) -> Result<Box<dyn OnlineTracker>> {
    let initial_pose = match args.init {
        InitArg::Measurement => None,
        InitArg::Truth | InitArg::Perturbed => {
            let truth = first.truth.as_ref().map(|t| t.camera_from_object).context(
                "--init truth|perturbed needs the truth of the first frame: a replayed simulated session",
            )?;
            Some(if args.init == InitArg::Perturbed { perturbed_start(&truth) } else { truth })
        }
    };
    let settings = TrackerSettings { initial_pose, ..TrackerSettings::default() };
    Ok(build_tracker(args.tracker.kind(), model, intrinsics, &settings)?)
}

/// Masks and poses for a live run: the sources that see the frames
/// (`aruco`, `external`) on any camera; a replayed session also brings its
/// own (`/vision/mask`, `/vision/pose`, moved onto the run's clock) and its
/// truth (`network`, `truth`).
fn measurements(
    args: &TrackArgs,
    session: Option<&Path>,
    offset_ns: i128,
    model: &ObjectModel,
    intrinsics: &slidetrack_core::CameraIntrinsics,
) -> Result<Box<dyn MeasurementSource>> {
    let which = args.measurements;
    let options = InputOptions {
        model: &args.model,
        model_scale: args.model_scale,
        object: args.object.as_deref(),
        measurements: which,
        init: args.init,
        recover: args.recover,
        aruco_config: args.aruco_config.as_deref(),
        external: Some(external_config(&args.external)),
    };
    Ok(match (which, session) {
        (MeasurementsArg::Aruco | MeasurementsArg::External, _) => {
            own_measurements(&options, model, intrinsics)?
        }
        (_, None) => bail!(
            "--measurements {} needs a replayed session's masks, poses or truth; a live camera has none \
             (use --measurements aruco or external, or a recording as the [rgbd] camera)",
            format!("{which:?}").to_lowercase()
        ),
        (MeasurementsArg::Input, Some(session)) => Box::new(Shifted {
            inner: SessionMeasurements::open(session, ReadOptions::default())?,
            offset_ns,
        }),
        (MeasurementsArg::Network, Some(_)) => Box::new(SlowNetwork::new(SlowNetworkConfig::default())),
        (MeasurementsArg::Truth, Some(_)) => Box::new(TruthSource { masks: true, poses: true }),
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
    args: &TrackArgs,
    path: &Path,
    rig: &Path,
    offset_ns: i128,
    model: &ObjectModel,
) -> Result<Recorder> {
    let options = RecorderOptions { overwrite: args.overwrite, ..RecorderOptions::default() };
    let metadata = BTreeMap::from([
        ("software_version".to_string(), env!("CARGO_PKG_VERSION").to_string()),
        ("tracker".to_string(), args.tracker.kind().name().to_string()),
        ("input".to_string(), format!("live: [rgbd] of {}", rig.display())),
        ("model".to_string(), model.origin.clone()),
        // Session time minus recording time of a replayed recording (ns).
        ("rgbd_replay_offset_ns".to_string(), offset_ns.to_string()),
    ]);
    Ok(Recorder::create_with_options(path, metadata, options)?)
}

fn report(args: &TrackArgs, summary: &serde_json::Value, camera: &LiveCamera) {
    for line in camera.counts() {
        tracing::info!("{line}");
    }
    if args.json {
        println!("{}", serde_json::to_string_pretty(summary).unwrap_or_default());
        return;
    }
    let name = args.tracker.kind().name();
    println!(
        "{name} live: {} of {} frames tracked in {:.1} s, {:.0} fps (tracker only)",
        summary["tracked"],
        summary["frames"],
        summary["seconds"].as_f64().unwrap_or(0.0),
        summary["tracker_fps"].as_f64().unwrap_or(0.0)
    );
    let p = camera.pair.counts();
    println!(
        "pairing: {} pairs, {} colour and {} depth frames unpaired, {} pairs skipped while the tracker was behind",
        p.pairs, p.unpaired_color, p.unpaired_depth, p.skipped_pairs
    );
    for line in camera.counts() {
        println!("{line}");
    }
    if let Some(m) = summary["metrics"].as_object() {
        println!(
            "against the recording's truth: ADD-AUC {:.2}%, position RMSE {:.2} cm, rotation RMSE {:.2} deg",
            m["add_auc_percent"].as_f64().unwrap_or(f64::NAN),
            m["position_rmse_cm"].as_f64().unwrap_or(f64::NAN),
            m["rotation_rmse_deg"].as_f64().unwrap_or(f64::NAN)
        );
    }
    if let Some(out) = &args.out {
        println!("frames and estimates written to {}", out.display());
    }
}
