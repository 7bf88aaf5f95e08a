//! One RGB-D camera for every use (`[hw.camera] kind = "rgbd"`): the
//! `[rgbd]` camera, opened once, is read on a thread of its own, and each
//! colour-and-depth pair goes
//!
//! - to the session: `/rgbd/color` (JPEG), `/rgbd/depth` (16-bit PNG) and,
//!   once, `/rgbd/calibration`;
//! - to the trial's marker detection, as a [`Camera`] of the colour frames
//!   ([`SharedColor`]; the observer records them on `/camera/image` as for
//!   any marker camera);
//! - to a vision tracker, as an [`RgbdSource`] ([`SharedFrames`]), when one
//!   takes it.
//!
//! V4L2 lets one process stream a node once: this is how the marker's
//! ground truth, a vision tracker and the recording share the device.
//!
//! A slow consumer never stops the camera nor the trial: one thread only
//! reads the camera and hands each pair to a second that encodes, records
//! and hands on; when that one is behind, pairs are dropped and counted
//! (logged once when it starts, and in the lines [`SharedRgbd::stop`]
//! returns), as are the frames a full marker or vision queue refuses, and
//! the images the session's writer refuses (its `images_dropped`). The
//! camera's threads and the thread that takes its pairs (a vision tracker)
//! run at a lower priority (nice 9), behind the trial: on busy
//! cores a trial's control loop must never find its tactile data stale
//! (the protocol aborts then) because images were being encoded.

use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::Duration;

use anyhow::{Context, Result, anyhow};
use crossbeam_channel::{Receiver, RecvTimeoutError, SendTimeoutError, Sender, TryRecvError, TrySendError};
use slidetrack_core::{Camera, CameraIntrinsics, DeviceError, ErrorKind, Frame};
use slidetrack_session::Logger;
use slidetrack_vision::VisionError;
use slidetrack_vision::input::{CameraPair, RgbdSample, RgbdSource, encode_color_jpeg};
use slidetrack_vision::record::RgbdChannels;
use thread_priority::{ThreadPriority, ThreadPriorityValue, set_current_thread_priority};

use super::camera::{LiveCamera, StreamCounts};

mod tally;

use tally::Tally;
pub use tally::{RGBD_CAMERA_METADATA, TallyCounts};

/// JPEG quality of the recorded colour frames.
const JPEG_QUALITY: i32 = 90;
/// Colour frames waiting for the trial's marker detection; older ones are dropped.
const MARKER_QUEUE: usize = 8;
/// Pairs read from the camera, waiting to be encoded and recorded; newer
/// ones are dropped while the recorder is behind (a live camera).
const RECORD_QUEUE: usize = 4;
/// Pairs waiting for the vision tracker (a live camera: newer ones are
/// dropped while it is behind; a replay of every frame: the camera waits).
const VISION_QUEUE: usize = 2;

/// Why the camera's thread stopped early, shared with its consumers.
type Failure = Arc<Mutex<Option<String>>>;

/// The shared camera, before and while it records.
pub struct SharedRgbd {
    /// The camera until [`SharedRgbd::start`].
    pending: Option<CameraPair>,
    /// What each of its streams counted.
    counts: StreamCounts,
    intrinsics: CameraIntrinsics,
    every_frame: bool,
    /// Where the pairs go, until [`SharedRgbd::start`] moves them to the
    /// thread (whose end then ends the consumers' streams).
    senders: Option<(Sender<Frame>, Sender<RgbdSample>)>,
    stop: Arc<AtomicBool>,
    tally: Arc<Tally>,
    failure: Failure,
    threads: Vec<JoinHandle<()>>,
    /// The session it records to, once started: the counts go there at the end.
    logger: Option<Logger>,
    /// Test hook: time the recorder spends on each pair on top of its work
    /// (a slow disk or a loaded machine).
    pub(crate) recorder_delay: Duration,
    /// The recording replayed, and its offset (session minus recording time, ns).
    pub replay: Option<(PathBuf, i128)>,
}

/// The colour frames of the shared camera, as the trial's marker camera.
pub struct SharedColor {
    rx: Receiver<Frame>,
    intrinsics: CameraIntrinsics,
    device: String,
    failure: Failure,
}

/// The pairs of the shared camera, for a vision tracker.
pub struct SharedFrames {
    rx: Receiver<RgbdSample>,
    intrinsics: CameraIntrinsics,
    failure: Failure,
    /// Whether the reading thread was lowered behind the trial.
    lowered: bool,
}

impl SharedRgbd {
    /// Shares `camera` (every frame of a replay paced by its reader when
    /// `every_frame`): the camera itself, its colour frames and its pairs.
    pub fn new(camera: LiveCamera, every_frame: bool) -> (SharedRgbd, SharedColor, SharedFrames) {
        let replay = camera.replay.clone();
        let (pair, counts) = camera.split();
        let intrinsics = pair.intrinsics().clone();
        let (marker_tx, marker_rx) = crossbeam_channel::bounded(MARKER_QUEUE);
        let (vision_tx, vision_rx) = crossbeam_channel::bounded(VISION_QUEUE);
        let failure: Failure = Arc::default();
        let color = SharedColor {
            rx: marker_rx,
            intrinsics: intrinsics.clone(),
            device: "the [rgbd] camera (colour)".into(),
            failure: Arc::clone(&failure),
        };
        let frames = SharedFrames {
            rx: vision_rx,
            intrinsics: intrinsics.clone(),
            failure: Arc::clone(&failure),
            lowered: false,
        };
        let shared = SharedRgbd {
            pending: Some(pair),
            counts,
            intrinsics,
            every_frame,
            senders: Some((marker_tx, vision_tx)),
            stop: Arc::default(),
            tally: Arc::default(),
            failure,
            threads: Vec::new(),
            logger: None,
            recorder_delay: Duration::ZERO,
            replay,
        };
        (shared, color, frames)
    }

    /// The colour camera's intrinsics (those of every pair).
    pub fn intrinsics(&self) -> &CameraIntrinsics {
        &self.intrinsics
    }

    /// Starts reading the camera, recording every pair to `logger`'s
    /// session (the calibration first).
    pub fn start(&mut self, logger: &Logger) -> Result<()> {
        let pair = self.pending.take().context("the shared RGB-D camera was started already")?;
        let (marker_tx, vision_tx) = self.senders.take().context("the shared RGB-D camera was stopped")?;
        let channels = RgbdChannels::register(logger, &self.intrinsics)?;
        self.logger = Some(logger.clone());
        let (record_tx, record_rx) = crossbeam_channel::bounded(RECORD_QUEUE);
        let recorder = Recorder {
            logger: logger.clone(),
            channels,
            marker_tx,
            vision_tx,
            every_frame: self.every_frame,
            stop: Arc::clone(&self.stop),
            tally: Arc::clone(&self.tally),
            delay: self.recorder_delay,
        };
        let reader = Reader {
            record_tx,
            every_frame: self.every_frame,
            stop: Arc::clone(&self.stop),
            tally: Arc::clone(&self.tally),
        };
        let failure = Arc::clone(&self.failure);
        let record_failure = Arc::clone(&self.failure);
        let spawn = |name: &str, f: Box<dyn FnOnce() + Send>| {
            std::thread::Builder::new()
                .name(name.into())
                .spawn(move || {
                    run_behind_the_trial();
                    f();
                })
                .with_context(|| format!("cannot start the RGB-D camera's {name} thread"))
        };
        self.threads.push(spawn(
            "rgbd-record",
            Box::new(move || {
                if let Err(e) = recorder.run(&record_rx) {
                    fail(&record_failure, &e);
                }
            }),
        )?);
        self.threads.push(spawn(
            "rgbd-camera",
            Box::new(move || {
                let mut pair = pair;
                if let Err(e) = reader.run(&mut pair) {
                    fail(&failure, &e);
                }
            }),
        )?);
        Ok(())
    }

    /// Stops reading (before the session is finished) and says what was
    /// recorded, dropped, and what each stream counted; the camera's error,
    /// if it failed.
    pub fn stop(&mut self) -> Result<Vec<String>> {
        self.stop.store(true, Ordering::SeqCst);
        self.senders = None;
        for t in self.threads.drain(..).rev() {
            t.join().map_err(|_| anyhow!("the RGB-D camera's thread panicked"))?;
        }
        if let Some(logger) = self.logger.take()
            && let Err(e) = logger.metadata(RGBD_CAMERA_METADATA, self.tally.counts().to_map())
        {
            tracing::warn!("rgbd camera: cannot record its counts: {e}");
        }
        if let Some(e) = failed(&self.failure) {
            return Err(anyhow!("the RGB-D camera failed: {e}"));
        }
        let mut lines = vec![self.tally.line()];
        lines.extend(self.counts.lines());
        Ok(lines)
    }

    /// What was read, recorded and dropped so far.
    pub fn tally(&self) -> TallyCounts {
        self.tally.counts()
    }
}

/// Lowers the calling thread to nice 9 (thread-priority's cross-platform
/// 25 of 99), so that on busy cores the trial's threads come first (the
/// scheduler's weights 1024 against 137) and the camera still gets an
/// eighth of a contended core. A failure (no niceness per thread here) is
/// logged and ignored.
fn run_behind_the_trial() {
    let priority =
        ThreadPriorityValue::try_from(25u8).map_or(ThreadPriority::Min, ThreadPriority::Crossplatform);
    if let Err(e) = set_current_thread_priority(priority) {
        tracing::debug!("rgbd camera: cannot lower the priority of this thread: {e:?}");
    }
}

/// Records `e` as the camera's failure.
fn fail(failure: &Failure, e: &anyhow::Error) {
    if let Ok(mut f) = failure.lock() {
        f.get_or_insert_with(|| format!("{e:#}"));
    }
}

/// Starts `shared`, if any, on `logger`'s session.
pub fn start_recording(shared: Option<&mut SharedRgbd>, logger: &Logger) -> Result<()> {
    shared.map_or(Ok(()), |s| s.start(logger))
}

/// Stops `shared`, if any, before its session is finished, and logs what it
/// recorded (a warning when the camera failed: the session is kept).
pub fn stop_recording(shared: Option<SharedRgbd>) {
    let Some(mut shared) = shared else { return };
    match shared.stop() {
        Ok(lines) => lines.iter().for_each(|l| tracing::info!("{l}")),
        Err(e) => tracing::warn!("{e:#}"),
    }
}

impl Drop for SharedRgbd {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        for t in self.threads.drain(..).rev() {
            let _ = t.join();
        }
    }
}

/// The camera's thread: reads pairs and hands them to the recorder, never
/// waiting for it on a live camera.
struct Reader {
    record_tx: Sender<RgbdSample>,
    every_frame: bool,
    stop: Arc<AtomicBool>,
    tally: Arc<Tally>,
}

impl Reader {
    fn run(self, pair: &mut CameraPair) -> Result<()> {
        while !self.stop.load(Ordering::SeqCst) {
            let Some(sample) = pair.next_frame()? else { return Ok(()) };
            self.tally.read.fetch_add(1, Ordering::SeqCst);
            if self.every_frame {
                if !send_unless_stopped(&self.record_tx, sample, &self.stop) {
                    return Ok(());
                }
            } else if let Err(TrySendError::Full(_)) = self.record_tx.try_send(sample) {
                self.tally.drop_one(&self.tally.dropped_recorder_behind, "the recorder is behind");
            }
        }
        Ok(())
    }
}

/// Sends `item`, waiting while `tx` is full, until `stop`; whether it went
/// (or the receiver is gone, which ends the stream the same way).
fn send_unless_stopped<T>(tx: &Sender<T>, mut item: T, stop: &AtomicBool) -> bool {
    while !stop.load(Ordering::SeqCst) {
        match tx.send_timeout(item, Duration::from_millis(50)) {
            Ok(()) => return true,
            Err(SendTimeoutError::Disconnected(_)) => return false,
            Err(SendTimeoutError::Timeout(back)) => item = back,
        }
    }
    false
}

/// The recorder's thread: encodes and records each pair, hands it on.
struct Recorder {
    logger: Logger,
    channels: RgbdChannels,
    marker_tx: Sender<Frame>,
    vision_tx: Sender<RgbdSample>,
    every_frame: bool,
    stop: Arc<AtomicBool>,
    tally: Arc<Tally>,
    delay: Duration,
}

impl Recorder {
    fn run(self, pairs: &Receiver<RgbdSample>) -> Result<()> {
        // Ends when the reader does (its sender dropped), after the pairs it queued.
        for sample in pairs {
            std::thread::sleep(self.delay);
            let frame = &sample.frame;
            let jpeg = encode_color_jpeg(&frame.color, JPEG_QUALITY)?;
            if self.channels.log_pair_lossy(&self.logger, frame, &jpeg)? {
                self.tally.recorded.fetch_add(1, Ordering::SeqCst);
            } else {
                self.tally.drop_one(&self.tally.dropped_writer_behind, "the session writer is behind");
            }
            let color = Frame {
                t: frame.t,
                sequence: frame.sequence,
                pixels: Some(frame.color.clone()),
                encoded: Some(jpeg),
            };
            // The trial polls far more often than frames come: a full queue
            // means the trial is over or stuck, and the frame is dropped.
            if let Err(TrySendError::Full(_)) = self.marker_tx.try_send(color) {
                self.tally.drop_one(&self.tally.dropped_marker_behind, "the marker detection is behind");
            }
            self.to_vision(sample);
        }
        Ok(())
    }

    /// Hands `sample` to the vision tracker, if one listens: waiting for it
    /// on a replay of every frame, else dropping the pair while it is behind.
    fn to_vision(&self, sample: RgbdSample) {
        if self.every_frame {
            send_unless_stopped(&self.vision_tx, sample, &self.stop);
        } else if let Err(TrySendError::Full(_)) = self.vision_tx.try_send(sample) {
            self.tally.drop_one(&self.tally.dropped_vision_behind, "the vision tracker is behind");
        }
    }
}

/// The camera's error, if its thread stopped on one.
fn failed(failure: &Failure) -> Option<String> {
    failure.lock().ok().and_then(|f| f.clone())
}

impl Camera for SharedColor {
    /// # Contract
    /// Never blocks: the oldest colour frame not yet returned, `None` when
    /// none is waiting (and once the camera ended, a replay at its end); the
    /// camera's error once its thread stopped on one.
    fn poll(&mut self) -> Result<Option<Frame>, DeviceError> {
        match self.rx.try_recv() {
            Ok(frame) => Ok(Some(frame)),
            Err(TryRecvError::Empty) => Ok(None),
            Err(TryRecvError::Disconnected) => match failed(&self.failure) {
                Some(e) => Err(DeviceError::new(ErrorKind::Other, &self.device, e)),
                None => Ok(None),
            },
        }
    }

    fn intrinsics(&self) -> &CameraIntrinsics {
        &self.intrinsics
    }

    fn device(&self) -> &str {
        &self.device
    }
}

impl RgbdSource for SharedFrames {
    fn intrinsics(&self) -> &CameraIntrinsics {
        &self.intrinsics
    }

    /// Blocks until the camera's thread hands on a pair; `Ok(None)` once it
    /// stopped, its error if it failed. The first call lowers the calling
    /// thread (the tracker's) behind the trial.
    fn next_frame(&mut self) -> Result<Option<RgbdSample>, VisionError> {
        if !self.lowered {
            run_behind_the_trial();
            self.lowered = true;
        }
        loop {
            match self.rx.recv_timeout(Duration::from_millis(100)) {
                Ok(sample) => return Ok(Some(sample)),
                Err(RecvTimeoutError::Timeout) => continue,
                Err(RecvTimeoutError::Disconnected) => {
                    return match failed(&self.failure) {
                        Some(e) => Err(DeviceError::new(ErrorKind::Other, "the [rgbd] camera", e).into()),
                        None => Ok(None),
                    };
                }
            }
        }
    }
}

#[cfg(test)]
mod tests;
