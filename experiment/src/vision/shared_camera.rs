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

use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::Duration;

use anyhow::{Context, Result, anyhow};
use crossbeam_channel::{Receiver, RecvTimeoutError, SendTimeoutError, Sender, TryRecvError};
use slidetrack_core::{Camera, CameraIntrinsics, DeviceError, ErrorKind, Frame};
use slidetrack_session::Logger;
use slidetrack_vision::VisionError;
use slidetrack_vision::input::{CameraPair, RgbdSample, RgbdSource, encode_color_jpeg};
use slidetrack_vision::record::RgbdChannels;

use super::camera::{LiveCamera, StreamCounts};

/// JPEG quality of the recorded colour frames.
const JPEG_QUALITY: i32 = 90;
/// Colour frames waiting for the trial's marker detection; older ones are dropped.
const MARKER_QUEUE: usize = 8;
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
    recorded: Arc<AtomicU64>,
    failure: Failure,
    thread: Option<JoinHandle<()>>,
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
        let frames =
            SharedFrames { rx: vision_rx, intrinsics: intrinsics.clone(), failure: Arc::clone(&failure) };
        let shared = SharedRgbd {
            pending: Some(pair),
            counts,
            intrinsics,
            every_frame,
            senders: Some((marker_tx, vision_tx)),
            stop: Arc::default(),
            recorded: Arc::default(),
            failure,
            thread: None,
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
        let worker = Worker {
            logger: logger.clone(),
            channels,
            marker_tx,
            vision_tx,
            every_frame: self.every_frame,
            stop: Arc::clone(&self.stop),
            recorded: Arc::clone(&self.recorded),
        };
        let failure = Arc::clone(&self.failure);
        let thread = std::thread::Builder::new()
            .name("rgbd-camera".into())
            .spawn(move || {
                let mut pair = pair;
                if let Err(e) = worker.run(&mut pair)
                    && let Ok(mut f) = failure.lock()
                {
                    *f = Some(format!("{e:#}"));
                }
            })
            .context("cannot start the RGB-D camera's thread")?;
        self.thread = Some(thread);
        Ok(())
    }

    /// Stops reading (before the session is finished) and says what was
    /// recorded and what each stream counted; the camera's error, if it failed.
    pub fn stop(&mut self) -> Result<Vec<String>> {
        self.stop.store(true, Ordering::SeqCst);
        self.senders = None;
        if let Some(t) = self.thread.take() {
            t.join().map_err(|_| anyhow!("the RGB-D camera's thread panicked"))?;
        }
        if let Some(e) = self.failure.lock().ok().and_then(|f| f.clone()) {
            return Err(anyhow!("the RGB-D camera failed: {e}"));
        }
        let mut lines = vec![format!("rgbd camera: {} pairs recorded", self.recorded.load(Ordering::SeqCst))];
        lines.extend(self.counts.lines());
        Ok(lines)
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
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// The camera's thread: reads pairs, records them, hands them on.
struct Worker {
    logger: Logger,
    channels: RgbdChannels,
    marker_tx: Sender<Frame>,
    vision_tx: Sender<RgbdSample>,
    every_frame: bool,
    stop: Arc<AtomicBool>,
    recorded: Arc<AtomicU64>,
}

impl Worker {
    fn run(self, pair: &mut CameraPair) -> Result<()> {
        while !self.stop.load(Ordering::SeqCst) {
            let Some(sample) = pair.next_frame()? else { return Ok(()) };
            let frame = &sample.frame;
            let jpeg = encode_color_jpeg(&frame.color, JPEG_QUALITY)?;
            self.channels.log_frame(&self.logger, frame, &jpeg, None, None)?;
            self.recorded.fetch_add(1, Ordering::SeqCst);
            let color = Frame {
                t: frame.t,
                sequence: frame.sequence,
                pixels: Some(frame.color.clone()),
                encoded: Some(jpeg),
            };
            // The trial polls far more often than frames come: a full queue
            // means the trial is over or stuck, and the frame is dropped.
            let _ = self.marker_tx.try_send(color);
            self.to_vision(sample);
        }
        Ok(())
    }

    /// Hands `sample` to the vision tracker, if one listens: waiting for it
    /// on a replay of every frame, else dropping the pair while it is behind.
    fn to_vision(&self, mut sample: RgbdSample) {
        if !self.every_frame {
            let _ = self.vision_tx.try_send(sample);
            return;
        }
        while !self.stop.load(Ordering::SeqCst) {
            match self.vision_tx.send_timeout(sample, Duration::from_millis(50)) {
                Ok(()) | Err(SendTimeoutError::Disconnected(_)) => return,
                Err(SendTimeoutError::Timeout(back)) => sample = back,
            }
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
    /// stopped, its error if it failed.
    fn next_frame(&mut self) -> Result<Option<RgbdSample>, VisionError> {
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
