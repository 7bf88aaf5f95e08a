//! A tracker online on a live RGB-D camera: each frame goes to the
//! measurement source (masks and poses), then to the tracker, and, with a
//! recording, the frame (`/rgbd/*`) and the estimate (`/estimate/*/<tracker>`)
//! go to the session, with the masks and poses the tracker was given
//! (`/vision/mask`, `/vision/pose`). [`LiveTracking::on_sample`] is one frame;
//! [`LiveTracking::run`] the loop until the camera ends or a stop flag;
//! [`LiveTracking::spawn`] the loop on its own thread, beside a tactile
//! trial that records into the same session.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use nalgebra::Isometry3;
use slidetrack_core::CameraIntrinsics;
use slidetrack_session::Logger;

use crate::eval::TrackedFrame;
use crate::input::{RgbdSample, RgbdSource, encode_color_jpeg};
use crate::record::{EstimateChannels, RgbdChannels};
use crate::sources::{FrameTruth, MeasurementSource};
use crate::{
    ObjectModel, OnlineTracker, TrackedState, TrackerKind, TrackerSettings, VisionError, build_tracker,
};

/// JPEG quality of the recorded colour frames.
const JPEG_QUALITY: i32 = 90;

/// What a live run counted.
#[derive(Clone, Debug, Default)]
pub struct LiveCounts {
    /// Frames processed.
    pub frames: usize,
    /// Frames with an estimate.
    pub tracked: usize,
    /// Time spent in the tracker alone.
    pub busy: Duration,
}

impl LiveCounts {
    /// Frames per second the tracker alone could process.
    pub fn tracker_fps(&self) -> f64 {
        if self.busy.is_zero() { 0.0 } else { self.frames as f64 / self.busy.as_secs_f64() }
    }
}

/// The session a live run writes to, and its channels.
struct Recording {
    logger: Logger,
    rgbd: RgbdChannels,
    estimates: EstimateChannels,
    /// Record the frames too (else something else records them).
    frames: bool,
}

/// One tracker fed by one measurement source, frame by frame.
pub struct LiveTracking {
    kind: TrackerKind,
    model: ObjectModel,
    intrinsics: CameraIntrinsics,
    tracker: Box<dyn OnlineTracker>,
    measurements: Box<dyn MeasurementSource>,
    recording: Option<Recording>,
    counts: LiveCounts,
    /// The estimates of frames that carry a truth (replays), for scoring.
    results: Vec<TrackedFrame>,
    last_pose: Option<Isometry3<f64>>,
}

impl LiveTracking {
    /// A `kind` tracker of `model` on frames of `intrinsics`, started as
    /// `settings` say, fed by `measurements`.
    pub fn new(
        kind: TrackerKind,
        model: ObjectModel,
        intrinsics: CameraIntrinsics,
        settings: &TrackerSettings,
        measurements: Box<dyn MeasurementSource>,
    ) -> Result<LiveTracking, VisionError> {
        let tracker = build_tracker(kind, &model, &intrinsics, settings)?;
        Ok(LiveTracking {
            kind,
            model,
            intrinsics,
            tracker,
            measurements,
            recording: None,
            counts: LiveCounts::default(),
            results: Vec::new(),
            last_pose: None,
        })
    }

    /// Also records each frame and estimate on `logger` (`/rgbd/*`,
    /// `/estimate/*/<tracker>`).
    pub fn recording_to(mut self, logger: &Logger) -> Result<LiveTracking, VisionError> {
        self.recording = Some(Recording {
            logger: logger.clone(),
            rgbd: RgbdChannels::register(logger, &self.intrinsics)?,
            estimates: EstimateChannels::register(logger, self.kind)?,
            frames: true,
        });
        Ok(self)
    }

    /// Records the measurements and estimates on `logger` (`/vision/*`,
    /// `/estimate/*/<tracker>`) but not the frames nor the calibration:
    /// the camera, shared, records those itself.
    pub fn recording_estimates_to(mut self, logger: &Logger) -> Result<LiveTracking, VisionError> {
        self.recording = Some(Recording {
            logger: logger.clone(),
            rgbd: RgbdChannels::attach(logger)?,
            estimates: EstimateChannels::register(logger, self.kind)?,
            frames: false,
        });
        Ok(self)
    }

    /// The tracker.
    pub fn kind(&self) -> TrackerKind {
        self.kind
    }

    /// The object model.
    pub fn model(&self) -> &ObjectModel {
        &self.model
    }

    /// What the run counted so far.
    pub fn counts(&self) -> &LiveCounts {
        &self.counts
    }

    /// The estimates of the frames that carried a truth.
    pub fn results(&self) -> &[TrackedFrame] {
        &self.results
    }

    /// The measurement source's summary line, if it has one.
    pub fn measurement_summary(&self) -> Option<String> {
        self.measurements.summary()
    }

    /// One frame: its masks and poses, the tracker's step, the recording.
    pub fn on_sample(&mut self, sample: RgbdSample) -> Result<Option<TrackedState>, VisionError> {
        let frame_truth = sample.truth.as_ref().zip(sample.truth_mask.as_ref());
        let arrivals = self.measurements.on_rgbd_frame(
            &sample.frame,
            frame_truth.map(|(t, m)| FrameTruth { camera_from_object: &t.camera_from_object, mask: m }),
        )?;
        let started = Instant::now();
        let state = self.tracker.process(&sample.frame, &arrivals)?;
        self.counts.busy += started.elapsed();
        if let Some(r) = &self.recording {
            if r.frames {
                let jpeg = encode_color_jpeg(&sample.frame.color, JPEG_QUALITY)?;
                r.rgbd.log_frame(&r.logger, &sample.frame, &jpeg, sample.truth.as_ref(), None)?;
            }
            // What the tracker was given, so that a replay of the session
            // (`--measurements input`) gives it the same.
            for m in &arrivals.masks {
                r.rgbd.log_vision_mask(&r.logger, m.frame_t, m.arrival_t, &m.value)?;
            }
            for p in &arrivals.poses {
                r.rgbd.log_vision_pose(&r.logger, p.frame_t, p.arrival_t, &p.value)?;
            }
            if let Some(s) = &state {
                r.estimates.log(&r.logger, s)?;
            }
        }
        if let Some(p) = arrivals.latest_pose() {
            self.last_pose = Some(p.value);
        }
        self.counts.frames += 1;
        self.counts.tracked += usize::from(state.is_some());
        if let Some(truth) = sample.truth {
            self.results.push(TrackedFrame {
                truth,
                flow_velocity: state.as_ref().and_then(|s| s.flow_velocity),
                estimate: state.as_ref().map(|s| s.estimate),
                last_measured_pose: self.last_pose,
            });
        }
        Ok(state)
    }

    /// Frames from `camera` until it ends, `stop` is set or `until` passes.
    pub fn run(
        &mut self,
        camera: &mut dyn RgbdSource,
        stop: &AtomicBool,
        until: Option<Instant>,
    ) -> Result<(), VisionError> {
        while !stop.load(Ordering::SeqCst) && until.is_none_or(|u| Instant::now() < u) {
            let Some(sample) = camera.next_frame()? else { break };
            self.on_sample(sample)?;
        }
        Ok(())
    }

    /// [`LiveTracking::run`] on its own thread until the camera ends or
    /// [`LiveThread::stop`]; the thread gives back the tracking and how the
    /// loop ended.
    pub fn spawn(self, mut camera: Box<dyn RgbdSource + Send>) -> LiveThread {
        let stop = Arc::new(AtomicBool::new(false));
        let flag = Arc::clone(&stop);
        let handle =
            std::thread::Builder::new().name(format!("live-{}", self.kind.name())).spawn(move || {
                let mut tracking = self;
                let ended = tracking.run(camera.as_mut(), &flag, None);
                (tracking, ended)
            });
        LiveThread { stop, handle: Some(handle) }
    }
}

/// The loop's result: the tracking (counts, results) and how it ended.
pub type LiveOutcome = (LiveTracking, Result<(), VisionError>);

/// A [`LiveTracking`] running on its own thread ([`LiveTracking::spawn`]).
/// Dropping it stops and joins the thread.
pub struct LiveThread {
    stop: Arc<AtomicBool>,
    handle: Option<std::io::Result<JoinHandle<LiveOutcome>>>,
}

impl LiveThread {
    /// Stops the loop after its current frame and waits for it; fails when
    /// the thread could not start or panicked (the error says which).
    pub fn stop(mut self) -> Result<LiveOutcome, VisionError> {
        self.join(true)
    }

    /// Waits for the loop to reach the end of its frames (a recording).
    pub fn wait_for_end(mut self) -> Result<LiveOutcome, VisionError> {
        self.join(false)
    }

    fn join(&mut self, stop: bool) -> Result<LiveOutcome, VisionError> {
        if stop {
            self.stop.store(true, Ordering::SeqCst);
        }
        let lost = |detail: String| VisionError::BadValue { what: "live vision thread", detail };
        match self.handle.take() {
            Some(Ok(handle)) => handle.join().map_err(|_| lost("it panicked".into())),
            Some(Err(e)) => Err(lost(format!("it could not start: {e}"))),
            None => Err(lost("it was stopped already".into())),
        }
    }
}

impl Drop for LiveThread {
    fn drop(&mut self) {
        if self.handle.is_some() {
            let _ = self.join(true);
        }
    }
}
