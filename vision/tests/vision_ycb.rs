//! MaskUKF on real YCB-Video frames (`../shared/testdata/rgbd/`). The ten
//! frames move the objects by less than 1 cm and 1 degree, so a tracker that
//! never moves would pass a test started at the truth. Here the tracker
//! starts 3 cm and 10 degrees off every visible object and runs over the
//! frames played forward and back four times (46 frames, 1.5 s, the truth
//! continuous at the turns); over the second half it must be within 1.5 cm
//! and 7 degrees at every frame. It reaches 0.8 cm and 4.3 degrees; a
//! tracker that stays at its start is 2.8-3.9 cm and 9.8-10.5 degrees off.

use std::path::PathBuf;

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use slidetrack_core::{CameraIntrinsics, TimeNs};
use slidetrack_estimators::metrics::{position_error_m, rotation_error_deg};
use slidetrack_vision::eval::{Scored, score, track};
use slidetrack_vision::input::{RgbdSample, RgbdSource, YCB_CLASSES, YcbDirectory, read_meta};
use slidetrack_vision::sources::TruthSource;
use slidetrack_vision::{ObjectModel, TrackerKind, TrackerSettings, VisionError, build_tracker};

fn testdata() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../shared/testdata/rgbd")
}

fn frames_dir() -> PathBuf {
    testdata().join("ycbv-0000/data/0000")
}

/// The frames of a directory played forward, back, forward... (`0 1 .. 9 8
/// .. 0 1 ..`), `count` frames at 30 Hz with their truth.
struct PingPong {
    frames: Vec<RgbdSample>,
    intrinsics: CameraIntrinsics,
    count: usize,
    next: usize,
}

impl PingPong {
    fn new(mut dir: YcbDirectory, count: usize) -> PingPong {
        let intrinsics = dir.intrinsics().clone();
        let mut frames = Vec::new();
        while let Some(s) = dir.next_frame().expect("the YCB-Video test frames read") {
            frames.push(s);
        }
        PingPong { frames, intrinsics, count, next: 0 }
    }
}

impl RgbdSource for PingPong {
    fn intrinsics(&self) -> &CameraIntrinsics {
        &self.intrinsics
    }

    fn next_frame(&mut self) -> Result<Option<RgbdSample>, VisionError> {
        if self.next >= self.count {
            return Ok(None);
        }
        let period = 2 * self.frames.len() - 2;
        let phase = self.next % period;
        let index = if phase < self.frames.len() { phase } else { period - phase };
        let mut sample = self.frames[index].clone();
        let t = TimeNs((self.next as f64 / 30.0 * 1e9).round() as u64);
        sample.frame.t = t;
        sample.frame.sequence = self.next as u64;
        if let Some(truth) = sample.truth.as_mut() {
            truth.t = t;
        }
        self.next += 1;
        Ok(Some(sample))
    }
}

/// `truth` moved 3 cm along (1, 1, 1) and turned 10 degrees about the
/// camera's z axis.
fn off_by_3_cm_and_10_deg(truth: &Isometry3<f64>) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::from(truth.translation.vector + Vector3::new(1.0, 1.0, 1.0).normalize() * 0.03),
        UnitQuaternion::from_scaled_axis(Vector3::z() * 10f64.to_radians()) * truth.rotation,
    )
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
fn maskukf_started_3_cm_and_10_degrees_off_converges_on_every_visible_object() {
    let meta = read_meta(&frames_dir().join("000001-meta.mat")).unwrap();
    for &class in &meta.cls_indexes {
        let name = YCB_CLASSES[class as usize - 1];
        let model =
            ObjectModel::load(&testdata().join("ycbv-models").join(name).join("points.xyz"), 1.0).unwrap();
        let directory = YcbDirectory::open(&frames_dir(), class, None).unwrap();
        assert_eq!(directory.len_hint(), Some(10));
        let mut source = PingPong::new(directory, 46);
        let start = off_by_3_cm_and_10_deg(&meta.pose_of(class).unwrap());
        let settings = TrackerSettings { initial_pose: Some(start), ..TrackerSettings::default() };
        let mut tracker =
            build_tracker(TrackerKind::MaskUkf, &model, source.intrinsics(), &settings).unwrap();
        let mut masks = TruthSource { masks: true, poses: false };
        let frames = track(&mut source, &mut masks, Some(tracker.as_mut()), |_, _| {}).unwrap();
        assert_eq!(frames.len(), 46);
        let (mut worst_cm, mut worst_deg) = (0.0f64, 0.0f64);
        for (k, f) in frames.iter().enumerate().skip(23) {
            let e = f.estimate.unwrap().camera_from_object;
            let dp_cm = position_error_m(&e, &f.truth.camera_from_object) * 100.0;
            let dr_deg = rotation_error_deg(&e, &f.truth.camera_from_object);
            assert!(dp_cm < 1.5 && dr_deg < 7.0, "{name} frame {k}: {dp_cm:.2} cm, {dr_deg:.2} deg");
            worst_cm = worst_cm.max(dp_cm);
            worst_deg = worst_deg.max(dr_deg);
        }
        let metrics = score(&frames, 23, Scored::Tracker, &model.object_points().unwrap());
        println!(
            "{name}: second half worst {worst_cm:.2} cm, {worst_deg:.2} deg; ADI-AUC {:.2}%, ADD-AUC {:.2}%, \
             position RMSE {:.3} cm, rotation RMSE {:.2} deg",
            metrics.adi_auc_percent,
            metrics.add_auc_percent,
            metrics.position_rmse_cm,
            metrics.rotation_rmse_deg
        );
        assert!(metrics.adi_auc_percent > 95.0, "{name}: {}", metrics.adi_auc_percent);
    }
}

/// The symmetry axes of `symmetry_of` fit the real model points: turning a
/// can, the bowl or the marker about its axis leaves the points where they
/// were (ADI under 3 mm, ADD several times larger), and the rotation error
/// modulo the symmetry is 0 for that turn; a box turned the same way does
/// move.
#[test]
fn the_symmetric_ycb_models_are_unchanged_by_turns_about_their_axes() {
    use slidetrack_estimators::metrics::{add_m, adi_m};
    use slidetrack_estimators::orientation::{Symmetry, rotation_error_modulo_symmetry_deg};
    let truth = Isometry3::from_parts(Translation3::new(0.0, 0.0, 0.7), UnitQuaternion::identity());
    for name in [
        "002_master_chef_can",
        "005_tomato_soup_can",
        "007_tuna_fish_can",
        "024_bowl",
        "040_large_marker",
        "009_gelatin_box",
    ] {
        let model =
            ObjectModel::load(&testdata().join("ycbv-models").join(name).join("points.xyz"), 1.0).unwrap();
        let points = model.object_points().unwrap();
        let axis = match model.symmetry {
            Symmetry::Axis { axis_in_object } => axis_in_object,
            Symmetry::None => Vector3::z_axis(),
        };
        let turned = Isometry3::from_parts(truth.translation, UnitQuaternion::from_axis_angle(&axis, 1.0));
        let (add, adi) = (add_m(&turned, &truth, &points), adi_m(&turned, &truth, &points));
        let modulo = rotation_error_modulo_symmetry_deg(&turned, &truth, points.symmetry());
        println!(
            "{name}: ADD {:.1} mm, ADI {:.1} mm, error modulo symmetry {modulo:.1} deg",
            add * 1e3,
            adi * 1e3
        );
        assert!(add > 0.005 && add > 2.0 * adi, "{name}");
        if name == "009_gelatin_box" {
            assert_eq!(model.symmetry, Symmetry::None);
            assert!(adi > 0.004 && modulo > 57.0, "{name}: {adi} m, {modulo} deg");
        } else {
            assert!(adi < 0.003 && modulo < 1e-6, "{name}: {adi} m, {modulo} deg");
        }
    }
}

#[test]
fn a_missing_model_or_directory_is_a_clear_error() {
    let e = ObjectModel::load(&testdata().join("ycbv-models/no_such_object/points.xyz"), 1.0).unwrap_err();
    assert!(e.to_string().contains("no_such_object"), "{e}");
    let e = YcbDirectory::open(&testdata().join("no_such_dir"), 1, None).err().unwrap();
    assert!(e.to_string().contains("no_such_dir"), "{e}");
}
