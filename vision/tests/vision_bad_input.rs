//! Bad input through the online trackers: an empty mask, a depth frame of
//! zeros, a gross outlier among the pose measurements and a frame of the
//! wrong size. Neither tracker panics or puts a NaN in its state; the
//! fallbacks are the documented ones (MaskUKF: the virtual point cloud of
//! Sec. 4.1.6; ROFT: the depth test (5.20) for poses, prediction for frames
//! without depth) and both are back on the object afterwards.
#![expect(clippy::unwrap_used, reason = "test code: a failed unwrap is a failed test")]

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use slidetrack_estimators::maskukf::MeasurementUsed;
use slidetrack_estimators::metrics::position_error_m;
use slidetrack_estimators::roft::{Mask, PoseUse};
use slidetrack_sim::rgbd::{FastSequence, FastSequenceConfig, RgbdSceneConfig, SimObjectKind};
use slidetrack_vision::cloud::mask;
use slidetrack_vision::sources::{Arrivals, Delayed};
use slidetrack_vision::{ObjectModel, StepNote, TrackerKind, TrackerSettings, VisionError, build_tracker};

const EMPTY_MASK: u64 = 10;
const ZERO_DEPTH: u64 = 13;
const OUTLIER_POSE: u64 = 16;
const WRONG_SIZE: u64 = 18;

fn sequence() -> FastSequence {
    let mut config = FastSequenceConfig::new(SimObjectKind::SugarBox, 1.2, 31);
    config.scene.intrinsics = RgbdSceneConfig::qvga_intrinsics();
    config.motion.max_speed_mps = 0.2;
    config.motion.max_angular_speed_dps = 60.0;
    FastSequence::new(config).unwrap()
}

/// 30 cm and 120 degrees off: a gross outlier of a pose network.
fn outlier(truth: &Isometry3<f64>) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::from(truth.translation.vector + Vector3::new(0.3, -0.1, 0.05)),
        UnitQuaternion::from_scaled_axis(Vector3::new(0.0, 120f64.to_radians(), 0.0)) * truth.rotation,
    )
}

#[test]
fn bad_frames_never_panic_or_put_nan_in_either_tracker() {
    let sequence = sequence();
    let model = ObjectModel::from_mesh("sugar_box", sequence.mesh().clone());
    let intrinsics = sequence.intrinsics().clone();
    for kind in [TrackerKind::MaskUkf, TrackerKind::Roft] {
        let settings = TrackerSettings {
            initial_pose: Some(sequence.truth(0).camera_from_object),
            ..TrackerSettings::default()
        };
        let mut tracker = build_tracker(kind, &model, &intrinsics, &settings).unwrap();
        let mut last_error_m = f64::NAN;
        for k in 0..sequence.len() {
            let (mut frame, inside, truth) = sequence.frame(k);
            let seq = frame.sequence;
            let mut m = mask(frame.depth.width, frame.depth.height, &inside).unwrap();
            let mut pose = truth.camera_from_object;
            if seq == EMPTY_MASK {
                m = Mask::empty(frame.depth.width, frame.depth.height);
            }
            if seq == ZERO_DEPTH {
                frame.depth.data.iter_mut().for_each(|d| *d = 0);
            }
            if seq == OUTLIER_POSE {
                pose = outlier(&truth.camera_from_object);
            }
            if seq == WRONG_SIZE {
                let mut small = frame.clone();
                small.depth.width = 10;
                small.depth.height = 10;
                small.depth.data.truncate(100);
                let e = tracker.process(&small, &Arrivals::default()).unwrap_err();
                assert!(matches!(e, VisionError::SizeMismatch { .. }), "{e}");
                assert!(e.to_string().contains("10x10"), "{e}");
            }
            let t = frame.t;
            // Poses every 3rd frame (ROFT), masks every frame.
            let poses = if kind == TrackerKind::Roft && (seq % 3 == 1 || seq == OUTLIER_POSE) {
                vec![Delayed { frame_t: t, arrival_t: t, value: pose }]
            } else {
                vec![]
            };
            let arrivals = Arrivals { masks: vec![Delayed { frame_t: t, arrival_t: t, value: m }], poses };
            let state = tracker.process(&frame, &arrivals).unwrap().unwrap();
            assert!(state.estimate.is_finite(), "{} frame {seq}: {:?}", kind.name(), state.estimate);
            match (&state.note, seq) {
                (StepNote::MaskUkf { used, .. }, EMPTY_MASK) => {
                    assert_eq!(*used, MeasurementUsed::VirtualNoMask)
                }
                (StepNote::MaskUkf { used, .. }, ZERO_DEPTH) => {
                    assert_eq!(*used, MeasurementUsed::VirtualLowValidRatio)
                }
                (StepNote::Roft { pose, .. }, OUTLIER_POSE) => {
                    assert!(matches!(pose, PoseUse::Outlier { .. }), "{pose:?}")
                }
                _ => {}
            }
            last_error_m = position_error_m(&state.estimate.camera_from_object, &truth.camera_from_object);
        }
        println!("{}: {:.2} cm off at the end", kind.name(), last_error_m * 100.0);
        assert!(last_error_m < 0.02, "{}: {last_error_m}", kind.name());
    }
}
