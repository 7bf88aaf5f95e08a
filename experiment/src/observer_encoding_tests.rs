//! The observer with its image encoder thread ([`crate::image_encoder`])
//! records the same session as a camera that encodes its own frames. Its own
//! module: the observer uses the encoder, and these tests use both.

use std::collections::BTreeMap;
use std::time::Duration;

use slidetrack_control::{ObserverError, TrialObserver};
use slidetrack_core::{
    CameraIntrinsics, EncodedImage, Frame, Image, PixelFormat, TactileInfo, TimeNs, encode_jpeg,
};
use slidetrack_session::{
    ArucoDetection, ChannelMessage, CompressedImage, ReadOptions, Recorder, RecorderOptions, read_json,
};

use crate::image_encoder::ImageEncodeFn;
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
    let options = RecorderOptions { flush_interval: Duration::from_secs(3600), ..RecorderOptions::default() };
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
