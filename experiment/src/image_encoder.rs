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
                        job.out.fill_json(&CompressedImage::new(job.t, "camera", &encoded));
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

#[cfg(test)]
mod tests {
    use std::collections::BTreeMap;
    use std::time::Duration;

    use slidetrack_control::{ObserverError, TrialObserver};
    use slidetrack_core::{CameraIntrinsics, Frame, PixelFormat, TactileInfo, encode_jpeg};
    use slidetrack_session::{
        ArucoDetection, ChannelMessage, ReadOptions, Recorder, RecorderOptions, read_json,
    };

    use super::*;
    use crate::marker::MarkerSource;
    use crate::observer::SessionObserver;

    /// A detector that finds nothing, in a 32x24 camera.
    struct Blind(CameraIntrinsics);

    impl MarkerSource for Blind {
        fn detect(&mut self, _: &Frame) -> Result<ArucoDetection, ObserverError> {
            Ok(ArucoDetection::missed())
        }
        fn intrinsics(&self) -> &CameraIntrinsics {
            &self.0
        }
    }

    /// Frame `k`'s pixels: a gradient that moves.
    fn pixels(k: u64) -> Image {
        let data = (0..32 * 24).map(|i| (i as u64 * 3 + k * 17) as u8).collect();
        Image { width: 32, height: 24, format: PixelFormat::Gray8, data }
    }

    /// JPEG, except that frame 5's encoder fails.
    fn encode(image: &Image) -> Option<EncodedImage> {
        (image.data[0] != (5 * 17) as u8).then(|| encode_jpeg(image, 80).unwrap())
    }

    /// Records 12 frames, encoded by the camera or (`deferred`) by the observer's thread.
    fn record(path: &std::path::Path, deferred: bool) {
        let options =
            RecorderOptions { flush_interval: Duration::from_secs(3600), ..RecorderOptions::default() };
        let rec = Recorder::create_with_options(path, BTreeMap::new(), options).unwrap();
        let intrinsics = CameraIntrinsics {
            width: 32,
            height: 24,
            fx: 30.0,
            fy: 30.0,
            cx: 16.0,
            cy: 12.0,
            distortion: [0.0; 5],
        };
        let tactile = TactileInfo::one_module_per_finger("test", 100.0, "sim");
        let marker: Box<dyn MarkerSource> = Box::new(Blind(intrinsics));
        let observer = SessionObserver::new(rec.logger(), &tactile, Some(marker), false, Box::new(|_| {}));
        let encoder: Option<ImageEncodeFn> = deferred.then(|| Box::new(encode) as ImageEncodeFn);
        let mut observer = observer.unwrap().with_image_encoder(encoder).unwrap();
        for k in 0..12u64 {
            let image = pixels(k);
            let encoded = if deferred { None } else { encode(&image) };
            let t = TimeNs(k * 33_000_000);
            observer.on_frame(Frame { t, sequence: k, pixels: Some(image), encoded }).unwrap();
        }
        drop(observer);
        rec.finish().unwrap();
    }

    #[test]
    fn frames_encoded_on_the_encoder_thread_record_the_same_session_as_encoded_by_the_camera() {
        // Catches images written out of turn (after the detection of their
        // frame or a later frame's), lost, or a failed frame written anyway.
        let dir = tempfile::tempdir().unwrap();
        let (camera, thread) = (dir.path().join("camera.mcap"), dir.path().join("thread.mcap"));
        record(&camera, false);
        record(&thread, true);
        let (a, b) = (std::fs::read(&camera).unwrap(), std::fs::read(&thread).unwrap());
        assert!(a == b, "the sessions differ");
        let images = read_json::<CompressedImage>(&thread, CompressedImage::TOPIC, ReadOptions::default());
        assert_eq!(images.map(|v| v.len()).ok(), Some(11), "every frame's image but the failed one");
    }
}
