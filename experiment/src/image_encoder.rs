//! Encoding the camera's frames on a thread of their own, so that a
//! simulated trial renders, detects and steps its physics on one core while
//! the JPEG encoder (a third of a simulated trial's work) runs on another.
//!
//! The session stays byte-identical to encoding in place: the observer
//! queues each image message in its turn with
//! [`Logger::log_json_pending`](slidetrack_session::Logger::log_json_pending)
//! and this thread fills it; the writer waits for the payload when it gets
//! there. Nothing is dropped: a full queue of frames blocks the trial.

use std::sync::mpsc::{SyncSender, sync_channel};
use std::thread::JoinHandle;

use anyhow::{Context, Result};
use slidetrack_core::{EncodedImage, Image, TimeNs};
use slidetrack_session::{CompressedImage, PendingPayload};

/// Compresses one frame; `None` when it cannot (the frame is then recorded
/// without its image, as a camera whose encoder failed).
pub type ImageEncodeFn = Box<dyn FnMut(&Image) -> Option<EncodedImage> + Send>;

/// Frames waiting for the encoder before the trial blocks: enough to ride
/// over a frame that takes longer, few enough to bound the memory (0.3 MB a
/// frame at 640x480 gray).
const QUEUE_FRAMES: usize = 4;

/// One frame to encode into its pending `/camera/image` message.
struct Job {
    image: Image,
    t: TimeNs,
    out: PendingPayload,
}

/// The encoder thread; dropping it encodes the frames still queued, then
/// joins the thread.
pub struct ImageEncoderThread {
    jobs: Option<SyncSender<Job>>,
    thread: Option<JoinHandle<()>>,
}

impl ImageEncoderThread {
    /// Starts the thread, which encodes with `encode`.
    pub fn start(mut encode: ImageEncodeFn) -> Result<ImageEncoderThread> {
        let (jobs, rx) = sync_channel::<Job>(QUEUE_FRAMES);
        let thread = std::thread::Builder::new()
            .name("image-encoder".into())
            .spawn(move || {
                for job in rx {
                    // Unfilled (encoder failed), the message is left out.
                    if let Some(encoded) = encode(&job.image) {
                        // The bytes of `fill_json`, without serde_json's escape scan of the data.
                        if let Ok(json) = CompressedImage::new(job.t, "camera", &encoded).to_json() {
                            job.out.fill(json);
                        }
                    }
                }
            })
            .context("cannot start the image encoder thread")?;
        Ok(ImageEncoderThread { jobs: Some(jobs), thread: Some(thread) })
    }

    /// Encodes `image`, taken at `t`, into `out` (the `/camera/image`
    /// message of its frame). Blocks while the encoder is [`QUEUE_FRAMES`]
    /// frames behind.
    pub fn submit(&self, image: Image, t: TimeNs, out: PendingPayload) {
        if let Some(jobs) = &self.jobs {
            // The thread gone (its encoder panicked): `out` drops unfilled.
            let _ = jobs.send(Job { image, t, out });
        }
    }
}

impl Drop for ImageEncoderThread {
    fn drop(&mut self) {
        drop(self.jobs.take());
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
    }
}
