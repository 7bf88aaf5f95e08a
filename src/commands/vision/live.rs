//! `slidetrack vision track --live --rig rig.toml`: a tracker online on the
//! rig's RGB-D camera (`[rgbd]`: V4L2 colour and depth nodes, or a recording
//! standing in for them), until Ctrl-C, `--duration` or the end of a
//! recording. With `--out`, the paired and registered frames (`/rgbd/*`),
//! the estimates (`/estimate/*/<tracker>`) and, on a replayed simulated
//! session, its truth (`/sim/object`) are recorded on the run's clock.

use std::collections::BTreeMap;
use std::path::Path;
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::{Context, Result, bail, ensure};
use serde_json::json;
use slidetrack_core::{CameraIntrinsics, Clock, TimeNs, WallClock};
use slidetrack_estimators::metrics::perturbed_start;
use slidetrack_experiment::rig_config::RigConfig;
use slidetrack_session::{ReadOptions, Recorder, RecorderOptions};
use slidetrack_vision::eval::{Scored, score};
use slidetrack_vision::input::{CameraPair, RecordedTruth, RgbdSample, RgbdSource};
use slidetrack_vision::live::LiveTracking;
use slidetrack_vision::sources::{
    Arrivals, FrameTruth, MeasurementSource, SessionMeasurements, SlowNetwork, SlowNetworkConfig, TruthSource,
};
use slidetrack_vision::{ObjectModel, TrackerSettings, VisionError};

use super::inputs::{InputOptions, load_model, own_measurements};
use super::live_camera::{self, LiveCamera};
use super::track::external_config;
use crate::cli::{InitArg, MeasurementsArg, VisionTrackArgs as TrackArgs};

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
    let truth = session.map(RecordedTruth::open).transpose()?;
    let offset_ns = replayed.as_ref().map_or(0, |(_, o)| *o);
    let intrinsics = camera.pair.intrinsics().clone();
    let measurements = measurements(args, session, offset_ns, &model, &intrinsics)?;
    let recorder =
        args.out.as_ref().map(|path| recorder(args, path, rig_path, offset_ns, &model)).transpose()?;
    if !quiet {
        eprintln!("tracking live on the [rgbd] camera of {} (Ctrl-C stops)", rig_path.display());
    }
    let stop = crate::commands::stop_flag("closing the session");
    let started = Instant::now();
    let until = args.duration.map(|d| started + Duration::from_secs_f64(d));
    let mut frames = WithTruth { camera: &mut camera.pair, truth, offset_ns };
    let mut tracking = None;
    if let Some(first) = frames.next_frame()? {
        let settings = TrackerSettings {
            initial_pose: initial_pose(args, &first)?,
            maskukf_pose_reset: args.pose_reset,
            ..TrackerSettings::default()
        };
        let mut t = LiveTracking::new(args.tracker.kind(), model, intrinsics, &settings, measurements)?;
        if let Some(r) = &recorder {
            t = t.recording_to(&r.logger())?;
        }
        t.on_sample(first)?;
        t.run(&mut frames, &stop, until)?;
        tracking = Some(t);
    }
    if let Some(r) = recorder {
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
    let summary = json!({
        "tracker": args.tracker.kind().name(),
        "rig": rig_path,
        "frames": counts.frames,
        "tracked": counts.tracked,
        "seconds": started.elapsed().as_secs_f64(),
        "tracker_fps": counts.tracker_fps(),
        "pairing": camera.pair.counts(),
        "streams": camera.counts(),
        "estimates": args.out,
        "metrics": metrics,
    });
    report(args, &summary, &camera);
    if let Some(summary) = tracking.measurement_summary() {
        eprintln!("{summary}");
    }
    Ok(())
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

/// Where the tracker starts, as `--init` says, from the first frame.
fn initial_pose(args: &TrackArgs, first: &RgbdSample) -> Result<Option<nalgebra::Isometry3<f64>>> {
    Ok(match args.init {
        InitArg::Measurement => None,
        InitArg::Truth | InitArg::Perturbed => {
            let truth = first.truth.as_ref().map(|t| t.camera_from_object).context(
                "--init truth|perturbed needs the truth of the first frame: a replayed simulated session",
            )?;
            Some(if args.init == InitArg::Perturbed { perturbed_start(&truth) } else { truth })
        }
    })
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
    intrinsics: &CameraIntrinsics,
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
