//! MaskUKF's pose reset (`TrackerSettings::maskukf_pose_reset`): a tracker
//! started 30 degrees off, fed the true masks (which turn it back over
//! about ten frames), starts again at a pose measurement that disagrees
//! with it by more than the reset's bounds, and only then; without the
//! reset the poses are ignored, as in the thesis.
#![expect(clippy::unwrap_used, reason = "test code: a failed unwrap is a failed test")]

use nalgebra::{Isometry3, UnitQuaternion, Vector3};
use slidetrack_estimators::metrics::rotation_error_deg;
use slidetrack_sim::rgbd::{FastSequence, FastSequenceConfig, RgbdSceneConfig, SimObjectKind};
use slidetrack_vision::cloud::mask;
use slidetrack_vision::sources::{Arrivals, Delayed};
use slidetrack_vision::{ObjectModel, PoseReset, StepNote, TrackerKind, TrackerSettings, build_tracker};

/// The frame at which the pose measurement comes.
const POSE_AT: usize = 3;

fn sequence() -> FastSequence {
    let mut config = FastSequenceConfig::new(SimObjectKind::CrackerBox, 0.5, 7);
    config.scene.intrinsics = RgbdSceneConfig::qvga_intrinsics();
    config.motion.max_speed_mps = 0.15;
    config.motion.max_angular_speed_dps = 45.0;
    FastSequence::new(config).unwrap()
}

/// Rotation errors (degrees) after each frame of MaskUKF started 30 degrees
/// off the first true pose, fed the true masks at every frame and the true
/// pose at frame `POSE_AT`, and whether it restarted at each frame.
fn run(reset: Option<PoseReset>, off_deg: f64) -> Vec<(f64, bool)> {
    let sequence = sequence();
    let model = ObjectModel::from_mesh("cracker_box", sequence.mesh().clone());
    let first = sequence.truth(0).camera_from_object;
    let turned =
        UnitQuaternion::from_scaled_axis(Vector3::new(0.0, 0.0, off_deg.to_radians())) * first.rotation;
    let settings = TrackerSettings {
        initial_pose: Some(Isometry3::from_parts(first.translation, turned)),
        maskukf_pose_reset: reset,
        ..TrackerSettings::default()
    };
    let mut tracker = build_tracker(TrackerKind::MaskUkf, &model, sequence.intrinsics(), &settings).unwrap();
    (0..sequence.len())
        .map(|k| {
            let (frame, inside, truth) = sequence.frame(k);
            let t = frame.t;
            let m = mask(frame.depth.width, frame.depth.height, &inside).unwrap();
            let poses = if k == POSE_AT {
                vec![Delayed { frame_t: t, arrival_t: t, value: truth.camera_from_object }]
            } else {
                vec![]
            };
            let arrivals = Arrivals { masks: vec![Delayed { frame_t: t, arrival_t: t, value: m }], poses };
            let state = tracker.process(&frame, &arrivals).unwrap().unwrap();
            let StepNote::MaskUkf { restarted, .. } = state.note else { panic!("{:?}", state.note) };
            (rotation_error_deg(&state.estimate.camera_from_object, &truth.camera_from_object), restarted)
        })
        .collect()
}

#[test]
fn maskukf_restarts_at_a_pose_that_disagrees_beyond_the_bounds_and_only_then() {
    let without = run(None, 30.0);
    let with = run(Some(PoseReset { position_m: 0.03, rotation_deg: 5.0 }), 30.0);
    let lenient = run(Some(PoseReset { position_m: 0.03, rotation_deg: 60.0 }), 30.0);
    println!("without: {without:.1?}\nwith:    {with:.1?}\nlenient: {lenient:.1?}");
    // Before the pose the runs are the same filter, still off by more than
    // the bounds when the pose comes.
    assert_eq!(without[..POSE_AT], with[..POSE_AT]);
    assert!(without[POSE_AT].0 > 5.0, "{without:?}");
    // A restart at the pose, and only there; on the object from then on,
    // and closer than the filter left to turn back by itself.
    let restarts: Vec<bool> = with.iter().map(|r| r.1).collect();
    assert_eq!(restarts, (0..with.len()).map(|k| k == POSE_AT).collect::<Vec<_>>());
    assert!(with[POSE_AT..].iter().all(|r| r.0 < 5.0), "{with:?}");
    assert!((POSE_AT..POSE_AT + 4).all(|k| with[k].0 < without[k].0 - 1.0), "{with:?}");
    // Without the reset, or within its bounds, the pose changes nothing.
    assert!(without.iter().chain(&lenient).all(|r| !r.1));
    assert_eq!(without, lenient);
}
