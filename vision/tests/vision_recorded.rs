//! A recorded session standing in for a live RGB-D camera: frames become
//! due on the session clock at their recorded time plus the replay's
//! offset, a slow reader loses the oldest, the replay ends, and through
//! [`CameraPair`] (colour delayed as on unsynchronised nodes, identity
//! extrinsics) every frame comes back as recorded, with its truth; paced
//! frame by frame, a slow reader on the wall clock loses none.

#![expect(clippy::unwrap_used, reason = "test code: a failed unwrap is a failed test")]

use std::collections::BTreeMap;
use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::time::Duration;

use nalgebra::Isometry3;
use slidetrack_core::{Camera, CameraIntrinsics, Clock, SimClock, TimeNs};
use slidetrack_session::Recorder;
use slidetrack_sim::rgbd::{FastSequence, FastSequenceConfig, SimObjectKind};
use slidetrack_vision::cloud::mask;
use slidetrack_vision::input::{
    CameraPair, DepthRegistration, PairSettings, RecordedRgbd, RecordedTruth, ReplayOptions, RgbdSource,
    SessionRgbd,
};
use slidetrack_vision::record::RgbdChannels;

const FRAMES: usize = 9;
const PERIOD_NS: u64 = 33_333_333;

/// A simulated session of 9 frames (0.3 s at 30 Hz) of 160x120 px.
fn record(path: &Path) {
    let mut config = FastSequenceConfig::new(SimObjectKind::SugarBox, 0.3, 5);
    config.scene.intrinsics = CameraIntrinsics {
        width: 160,
        height: 120,
        fx: 138.6,
        fy: 138.6,
        cx: 79.5,
        cy: 59.5,
        distortion: [0.0; 5],
    };
    let sequence = FastSequence::new(config).unwrap();
    assert_eq!(sequence.len(), FRAMES);
    let recorder = Recorder::create(path, BTreeMap::new()).unwrap();
    let logger = recorder.logger();
    let channels = RgbdChannels::register(&logger, sequence.intrinsics()).unwrap();
    for k in 0..sequence.len() {
        let (frame, inside, truth) = sequence.frame(k);
        let m = mask(frame.depth.width, frame.depth.height, &inside).unwrap();
        let png = slidetrack_vision::input::encode_depth_png(&frame.depth).unwrap();
        let color = slidetrack_core::EncodedImage {
            format: "png".into(),
            bytes: {
                // Lossless colour, so that replayed frames compare exactly.
                let rgb = &frame.color;
                let mut bytes = Vec::new();
                let mut encoder = png::Encoder::new(&mut bytes, rgb.width, rgb.height);
                encoder.set_color(png::ColorType::Rgb);
                encoder.write_header().unwrap().write_image_data(&rgb.data).unwrap();
                bytes
            },
        };
        assert!(!png.bytes.is_empty());
        channels.log_frame(&logger, &frame, &color, Some(&truth), Some(&m)).unwrap();
    }
    recorder.finish().unwrap();
}

fn options() -> ReplayOptions {
    ReplayOptions::default()
}

#[test]
fn frames_are_due_at_their_recorded_time_plus_the_offset() {
    let dir = tempfile::tempdir().unwrap();
    let session = dir.path().join("s.mcap");
    record(&session);
    let clock = SimClock::new();
    clock.sleep_until(TimeNs(5_000_000_000));
    let RecordedRgbd { mut color, mut depth, ended, offset_ns, .. } =
        RecordedRgbd::open_session(&session, Arc::new(clock.clone()), &options()).unwrap();
    // The first frame (recorded at 0) is due now, at 5 s.
    assert_eq!(offset_ns, 5_000_000_000);
    let first = depth.poll().unwrap().unwrap();
    assert_eq!(first.t, TimeNs(5_000_000_000));
    assert!(depth.poll().unwrap().is_none(), "the second frame is not due yet");
    clock.sleep_until(TimeNs(5_000_000_000 + PERIOD_NS - 1_000));
    assert!(depth.poll().unwrap().is_none(), "still not due 1 us before");
    clock.sleep_until(TimeNs(5_000_000_000 + PERIOD_NS + 1_000));
    assert_eq!(depth.poll().unwrap().unwrap().sequence, 1);
    // A reader far behind gets the newest four and loses the rest.
    clock.sleep_until(TimeNs(5_000_000_000 + 10 * PERIOD_NS));
    let mut got = Vec::new();
    while let Some(f) = depth.poll().unwrap() {
        got.push(f.sequence);
    }
    assert_eq!(got, vec![5, 6, 7, 8]);
    assert_eq!(depth.counts().lost(), 3);
    assert!(ended.load(Ordering::SeqCst), "the depth stream is over");
    // The colour stream runs on the same offset.
    let fifth = color.poll().unwrap().unwrap();
    assert_eq!(fifth.sequence, 5);
    assert!(fifth.t.0.abs_diff(5_000_000_000 + 5 * PERIOD_NS) < 10, "{:?}", fifth.t);
}

#[test]
fn a_camera_pair_on_the_replay_gives_back_every_recorded_frame_with_its_truth() {
    let dir = tempfile::tempdir().unwrap();
    let session = dir.path().join("s.mcap");
    record(&session);
    let clock = SimClock::new();
    let replay = RecordedRgbd::open_session(
        &session,
        Arc::new(clock.clone()),
        &ReplayOptions { color_delay_ns: 7_000_000, ..options() },
    )
    .unwrap();
    let intrinsics = replay.color.intrinsics().clone();
    let registration =
        DepthRegistration { depth_intrinsics: intrinsics.clone(), color_from_depth: Isometry3::identity() };
    let settings = PairSettings {
        color_intrinsics: intrinsics,
        depth_scale_m: 0.001,
        tolerance: Duration::from_millis(16),
        timeout: Duration::from_millis(100),
        registration: Some(registration),
    };
    let offset = replay.offset_ns;
    let mut pair =
        CameraPair::new(Box::new(replay.color), Box::new(replay.depth), settings).with_end(replay.ended);
    let mut recorded = SessionRgbd::open(&session, Default::default()).unwrap();
    let mut truth = RecordedTruth::open(&session).unwrap();
    for k in 0..FRAMES {
        // Time moves on by a frame; the colour frame 7 ms after the depth one.
        clock.sleep_until(TimeNs(k as u64 * PERIOD_NS + 8_000_000));
        let live = pair.next_frame().unwrap().unwrap().frame;
        let want = recorded.next_frame().unwrap().unwrap();
        assert_eq!(i128::from(live.t.0) - offset, i128::from(want.frame.t.0), "frame {k}");
        assert_eq!(live.color, want.frame.color, "frame {k}: colour");
        // Identity extrinsics: registration leaves the depth as recorded
        // (to within the footprint's edge pixels).
        let differ = live.depth.data.iter().zip(&want.frame.depth.data).filter(|(a, b)| a != b).count();
        assert!(differ * 100 < live.depth.data.len(), "frame {k}: {differ} depth pixels moved");
        let (pose, m) = truth.at(want.frame.t).unwrap();
        assert_eq!(pose.map(|p| p.camera_from_object), want.truth.map(|p| p.camera_from_object), "frame {k}");
        assert_eq!(m, want.truth_mask, "frame {k}");
    }
    // Every frame was paired; the replay ends.
    clock.sleep_until(TimeNs(10 * PERIOD_NS));
    assert!(pair.next_frame().unwrap().is_none());
    let counts = pair.counts();
    assert_eq!((counts.pairs, counts.skipped_pairs), (FRAMES as u64, 0), "{counts:?}");
}

/// Paced frame by frame, a reader slower than the frame rate (50 ms per
/// frame against 33 ms) on the wall clock gets every frame once, at its
/// recorded time plus the offset, and the replay ends. On the wall clock's
/// pace the same reader loses frames (the first test).
#[test]
fn every_frame_pacing_gives_a_slow_reader_every_frame_at_its_recorded_time() {
    let dir = tempfile::tempdir().unwrap();
    let session = dir.path().join("s.mcap");
    record(&session);
    let clock = slidetrack_core::WallClock::start();
    let options = ReplayOptions { color_delay_ns: 7_000_000, every_frame: true, ..options() };
    let replay = RecordedRgbd::open_session(&session, Arc::new(clock), &options).unwrap();
    let settings = PairSettings {
        color_intrinsics: replay.color.intrinsics().clone(),
        depth_scale_m: 0.001,
        tolerance: Duration::from_millis(16),
        timeout: Duration::from_millis(500),
        registration: None,
    };
    let (offset, pacer) = (replay.offset_ns, replay.pacer().unwrap());
    let mut pair = CameraPair::new(Box::new(replay.color), Box::new(replay.depth), settings)
        .with_end(replay.ended)
        .with_pacer(pacer);
    let mut times = Vec::new();
    while let Some(sample) = pair.next_frame().unwrap() {
        times.push(i128::from(sample.frame.t.0) - offset);
        std::thread::sleep(Duration::from_millis(50));
    }
    let recorded: Vec<i128> = (0..FRAMES as i128).map(|k| k * i128::from(PERIOD_NS)).collect();
    assert_eq!(times.len(), FRAMES, "{times:?}");
    for (got, want) in times.iter().zip(&recorded) {
        assert!(got.abs_diff(*want) < 1_000, "{times:?} against {recorded:?}");
    }
    let counts = pair.counts();
    assert_eq!((counts.pairs, counts.skipped_pairs, counts.unpaired_depth), (FRAMES as u64, 0, 0));
}
