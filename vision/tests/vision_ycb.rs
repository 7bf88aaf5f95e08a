//! MaskUKF on real YCB-Video frames (`../shared/testdata/rgbd/`): started at
//! the true pose, with the label images as masks, it keeps every visible
//! object within 1 cm and 5 degrees; the metrics give its ADI-AUC.

use std::path::PathBuf;

use slidetrack_estimators::metrics::{position_error_m, rotation_error_deg};
use slidetrack_vision::eval::{Scored, score, track};
use slidetrack_vision::input::{RgbdSource, YCB_CLASSES, YcbDirectory, read_meta};
use slidetrack_vision::sources::TruthSource;
use slidetrack_vision::{ObjectModel, TrackerKind, TrackerSettings, build_tracker};

fn testdata() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../shared/testdata/rgbd")
}

fn frames_dir() -> PathBuf {
    testdata().join("ycbv-0000/data/0000")
}

#[test]
fn the_meta_files_parse_to_rotations_and_intrinsics() {
    let meta = read_meta(&frames_dir().join("000001-meta.mat")).unwrap();
    assert_eq!(meta.cls_indexes, vec![8, 14, 21]);
    assert_eq!(meta.factor_depth, 10000.0);
    assert!((meta.intrinsics[0] - 1066.778).abs() < 1e-6 && (meta.intrinsics[3] - 241.3109).abs() < 1e-6);
    for pose in &meta.poses {
        let r = pose.rotation.to_rotation_matrix();
        assert!((r.matrix() * r.matrix().transpose() - nalgebra::Matrix3::identity()).norm() < 1e-5);
        assert!(pose.translation.z > 0.3 && pose.translation.z < 1.5);
    }
    // The gelatin box (class 8) as stored column-major in the file.
    let p = meta.pose_of(8).unwrap();
    assert!((p.translation.vector - nalgebra::Vector3::new(-0.0306, -0.0080, 0.5926)).norm() < 1e-3);
}

#[test]
fn maskukf_keeps_every_visible_object_within_1_cm_and_5_degrees() {
    let meta = read_meta(&frames_dir().join("000001-meta.mat")).unwrap();
    for &class in &meta.cls_indexes {
        let name = YCB_CLASSES[class as usize - 1];
        let model =
            ObjectModel::load(&testdata().join("ycbv-models").join(name).join("points.xyz"), 1.0).unwrap();
        let mut source = YcbDirectory::open(&frames_dir(), class, None).unwrap();
        assert_eq!(source.len_hint(), Some(10));
        let start = meta.pose_of(class).unwrap();
        let settings = TrackerSettings { initial_pose: Some(start), ..TrackerSettings::default() };
        let mut tracker =
            build_tracker(TrackerKind::MaskUkf, &model, source.intrinsics(), &settings).unwrap();
        let mut masks = TruthSource { masks: true, poses: false };
        let frames = track(&mut source, &mut masks, Some(tracker.as_mut()), |_, _| {}).unwrap();
        assert_eq!(frames.len(), 10);
        for (k, f) in frames.iter().enumerate() {
            let e = f.estimate.unwrap();
            let dp = position_error_m(&e.camera_from_object, &f.truth.camera_from_object);
            let dr = rotation_error_deg(&e.camera_from_object, &f.truth.camera_from_object);
            assert!(dp < 0.01 && dr < 5.0, "{name} frame {}: {:.2} cm, {dr:.2} deg", k + 1, dp * 100.0);
        }
        let metrics = score(&frames, 0, Scored::Tracker, &model.object_points().unwrap());
        println!(
            "{name}: ADI-AUC {:.2}%, ADD-AUC {:.2}%, position RMSE {:.3} cm, rotation RMSE {:.2} deg",
            metrics.adi_auc_percent,
            metrics.add_auc_percent,
            metrics.position_rmse_cm,
            metrics.rotation_rmse_deg
        );
        assert!(metrics.adi_auc_percent > 90.0, "{name}: {}", metrics.adi_auc_percent);
    }
}

#[test]
fn a_missing_model_or_directory_is_a_clear_error() {
    let e = ObjectModel::load(&testdata().join("ycbv-models/no_such_object/points.xyz"), 1.0).unwrap_err();
    assert!(e.to_string().contains("no_such_object"), "{e}");
    let e = YcbDirectory::open(&testdata().join("no_such_dir"), 1, None).err().unwrap();
    assert!(e.to_string().contains("no_such_dir"), "{e}");
}
