//! A tracker over a recorded input (`vision track --input`): a session or a
//! YCB-Video-style directory, its estimates optionally written to a session
//! and scored against the input's truth.

use std::path::Path;
use std::time::{Duration, Instant};

use anyhow::Result;
use slidetrack_session::{Recorder, RecorderOptions};
use slidetrack_vision::eval::{Scored, TrackedFrame, score};
use slidetrack_vision::input::RgbdSource;
use slidetrack_vision::record::EstimateChannels;
use slidetrack_vision::sources::{FrameTruth, MeasurementSource};
use slidetrack_vision::{ObjectModel, OnlineTracker, PoseReset, TrackerKind, TrackerSettings, build_tracker};

use super::input::{InputOptions, Prepared, check_pose_reset, prepare};
use super::{Metadata, SequenceMetrics};

/// The options of a tracking run over a recorded input.
#[derive(Clone)]
pub struct OfflineOptions<'a> {
    /// The session or YCB-Video-style directory.
    pub input: &'a Path,
    /// The model, measurements and start of the tracker on it.
    pub input_options: InputOptions<'a>,
    /// The tracker.
    pub kind: TrackerKind,
    /// MaskUKF: start again at a pose measurement this far from the estimate.
    pub pose_reset: Option<PoseReset>,
    /// Session file for the estimates (`/estimate/pose|transform|velocity/<tracker>`).
    pub out: Option<&'a Path>,
    /// Replace `out` if it exists.
    pub overwrite: bool,
}

/// A tracker opened on its input, ready to run.
pub struct OfflineTracking {
    source: Box<dyn RgbdSource>,
    measurements: Box<dyn MeasurementSource>,
    model: ObjectModel,
    tracker: Box<dyn OnlineTracker>,
    recorder: Option<(Recorder, EstimateChannels)>,
}

/// What a tracking run over an input did.
#[derive(Clone, Debug)]
pub struct OfflineSummary {
    /// Frames read.
    pub frames: usize,
    /// Frames with an estimate.
    pub tracked: usize,
    /// Frames per second of the tracker alone (this machine).
    pub tracker_fps: f64,
    /// The errors against the input's truth, when it has one.
    pub metrics: Option<SequenceMetrics>,
    /// What the measurement source delivered, when it says.
    pub measurement_summary: Option<String>,
}

impl OfflineTracking {
    /// Opens the input, the measurement source, the tracker and the session
    /// of `options`.
    pub fn open(options: &OfflineOptions<'_>) -> Result<OfflineTracking> {
        check_pose_reset(options.pose_reset, options.kind)?;
        let Prepared { source, measurements, model, intrinsics, initial_pose } =
            prepare(options.input, &options.input_options)?;
        let settings = TrackerSettings {
            initial_pose,
            maskukf_pose_reset: options.pose_reset,
            ..TrackerSettings::default()
        };
        let tracker = build_tracker(options.kind, &model, &intrinsics, &settings)?;
        let recorder = match options.out {
            Some(path) => {
                let recorder = recorder(options, path, &model.origin)?;
                let channels = EstimateChannels::register(&recorder.logger(), options.kind)?;
                Some((recorder, channels))
            }
            None => None,
        };
        Ok(OfflineTracking { source, measurements, model, tracker, recorder })
    }

    /// How many frames the input has, when it knows.
    pub fn len_hint(&self) -> Option<usize> {
        self.source.len_hint()
    }

    /// Tracks every frame of the input, calling `on_frame` after each.
    pub fn run(mut self, on_frame: &mut dyn FnMut()) -> Result<OfflineSummary> {
        let mut busy = Duration::ZERO;
        let (mut frames, mut tracked) = (0usize, 0usize);
        let mut results = Vec::new();
        let mut last_pose = None;
        while let Some(sample) = self.source.next_frame()? {
            let truth = sample.truth.as_ref().zip(sample.truth_mask.as_ref());
            let arrivals = self.measurements.on_rgbd_frame(
                &sample.frame,
                truth.map(|(t, m)| FrameTruth { camera_from_object: &t.camera_from_object, mask: m }),
            )?;
            if let Some(p) = arrivals.latest_pose() {
                last_pose = Some(p.value);
            }
            let started = Instant::now();
            let state = self.tracker.process(&sample.frame, &arrivals)?;
            busy += started.elapsed();
            frames += 1;
            if let Some(s) = &state {
                tracked += 1;
                if let Some((r, c)) = &self.recorder {
                    c.log(&r.logger(), s)?;
                }
            }
            if let Some(truth) = sample.truth {
                results.push(TrackedFrame {
                    truth,
                    flow_velocity: state.as_ref().and_then(|s| s.flow_velocity),
                    estimate: state.map(|s| s.estimate),
                    last_measured_pose: last_pose,
                });
            }
            on_frame();
        }
        if let Some((r, _)) = self.recorder {
            r.finish()?;
        }
        let tracker_fps = if busy.is_zero() { 0.0 } else { frames as f64 / busy.as_secs_f64() };
        let first = results.iter().position(|f| f.estimate.is_some()).unwrap_or(results.len());
        let metrics = (!results.is_empty() && first < results.len())
            .then(|| {
                self.model.object_points().map(|points| score(&results, first, Scored::Tracker, &points))
            })
            .transpose()?;
        let measurement_summary = self.measurements.summary();
        Ok(OfflineSummary { frames, tracked, tracker_fps, metrics, measurement_summary })
    }
}

/// The session for the estimates, with what produced them in its metadata.
fn recorder(options: &OfflineOptions<'_>, path: &Path, model: &str) -> Result<Recorder> {
    let recorder_options = RecorderOptions { overwrite: options.overwrite, ..RecorderOptions::default() };
    let metadata = Metadata::from([
        ("software_version".to_string(), env!("CARGO_PKG_VERSION").to_string()),
        ("tracker".to_string(), options.kind.name().to_string()),
        ("input".to_string(), options.input.display().to_string()),
        ("model".to_string(), model.to_string()),
    ]);
    Ok(Recorder::create_with_options(path, metadata, recorder_options)?)
}
