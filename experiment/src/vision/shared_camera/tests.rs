//! The shared camera with a deliberately slow recorder: the trial's colour
//! frames keep coming without an error, pairs are dropped and counted, and
//! every pair recorded is in the session, whole.

use std::collections::BTreeMap;
use std::time::Instant;

use slidetrack_core::{DepthImage, EncodedImage, Image, PixelFormat, TimeNs};
use slidetrack_session::{
    ChannelMessage, MessageReader, ReadOptions, Recorder, RecorderOptions, RgbdDepth, SessionInfo,
};
use slidetrack_vision::input::{PairSettings, encode_depth_png};

use super::*;

const PERIOD_NS: u64 = 5_000_000;

fn intrinsics() -> CameraIntrinsics {
    CameraIntrinsics { width: 64, height: 48, fx: 60.0, fy: 60.0, cx: 31.5, cy: 23.5, distortion: [0.0; 5] }
}

/// A stream delivering `image` every 5 ms of wall-clock time, stamped k * 5 ms.
struct Stream {
    image: EncodedImage,
    started: Instant,
    next: u64,
    intrinsics: CameraIntrinsics,
}

impl Camera for Stream {
    fn poll(&mut self) -> Result<Option<Frame>, DeviceError> {
        let t = self.next * PERIOD_NS;
        if (self.started.elapsed().as_nanos() as u64) < t {
            return Ok(None);
        }
        self.next += 1;
        Ok(Some(Frame { t: TimeNs(t), sequence: self.next, pixels: None, encoded: Some(self.image.clone()) }))
    }

    fn intrinsics(&self) -> &CameraIntrinsics {
        &self.intrinsics
    }

    fn device(&self) -> &str {
        "test stream"
    }
}

fn fast_camera() -> LiveCamera {
    let k = intrinsics();
    let rgb = Image { width: 64, height: 48, format: PixelFormat::Rgb8, data: vec![128; 64 * 48 * 3] };
    let depth = DepthImage {
        width: 64,
        height: 48,
        data: (0..64 * 48).map(|i| 500 + i as u16).collect(),
        scale_m: 0.001,
    };
    let started = Instant::now();
    let stream =
        |image| Box::new(Stream { image, started, next: 0, intrinsics: k.clone() }) as Box<dyn Camera>;
    let settings = PairSettings {
        color_intrinsics: k.clone(),
        depth_scale_m: 0.001,
        tolerance: Duration::from_millis(1),
        timeout: Duration::from_secs(2),
        registration: None,
    };
    let pair = CameraPair::new(
        stream(encode_color_jpeg(&rgb, 90).unwrap()),
        stream(encode_depth_png(&depth).unwrap()),
        settings,
    );
    LiveCamera::from_pair(pair)
}

#[test]
fn a_slow_recorder_drops_counted_pairs_and_never_fails_the_trial() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("shared.mcap");
    let recorder = Recorder::create_with_options(&path, BTreeMap::new(), RecorderOptions::default()).unwrap();
    let (mut shared, mut color, _frames) = SharedRgbd::new(fast_camera(), false);
    // 200 pairs a second, each taking the recorder 40 ms: it keeps up with one in eight.
    shared.recorder_delay = Duration::from_millis(40);
    shared.start(&recorder.logger()).unwrap();
    let started = Instant::now();
    let mut colour_frames = 0;
    while started.elapsed() < Duration::from_millis(800) {
        // The trial's marker camera: never an error.
        while let Some(frame) = color.poll().expect("the shared camera must not fail the trial") {
            assert!(frame.encoded.is_some());
            colour_frames += 1;
        }
        std::thread::sleep(Duration::from_millis(2));
    }
    let lines = shared.stop().expect("a slow recorder is no failure");
    let tally = shared.tally();
    assert!(lines[0].contains("dropped"), "{lines:?}");
    assert!(tally.dropped_recorder_behind > tally.recorded, "{tally:?}");
    assert!(tally.recorded >= 5, "{tally:?}");
    assert_eq!(tally.dropped_writer_behind, 0, "{tally:?}");
    // Stopped: the frames still queued, then the end, with no error either.
    while let Some(_frame) = color.poll().expect("a stopped shared camera is no failure") {
        colour_frames += 1;
    }
    assert_eq!(colour_frames, tally.recorded, "the marker gets every recorded pair's colour");
    recorder.finish().unwrap();
    // Every pair recorded before the stop is in the session, exactly.
    let depths: Vec<_> = MessageReader::open(&path, &[RgbdDepth::TOPIC], ReadOptions::default())
        .unwrap()
        .map(|m| serde_json::from_slice::<RgbdDepth>(&m.unwrap().data).unwrap().to_depth().unwrap())
        .collect();
    assert_eq!(depths.len() as u64, tally.recorded);
    assert!(depths.iter().all(|d| d.data.iter().enumerate().all(|(i, v)| *v == 500 + i as u16)));
    // The counts are in the session too.
    let info = SessionInfo::read(&path, ReadOptions::default()).unwrap();
    let record = &info.metadata[RGBD_CAMERA_METADATA];
    assert_eq!(record["pairs_recorded"], tally.recorded.to_string());
    assert_eq!(record["dropped_recorder_behind"], tally.dropped_recorder_behind.to_string());
}
