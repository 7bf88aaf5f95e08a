//! The ArUco source on frames of the simulated camera with a marker printed
//! on the object.

use nalgebra::{Isometry3, Translation3, UnitQuaternion};
use slidetrack_core::{RgbdFrame, TimeNs};
use slidetrack_estimators::metrics::{position_error_m, rotation_error_deg};
use slidetrack_sim::rgbd::{MarkerDecal, RgbdScene, RgbdSceneConfig, SimObjectKind};

use super::*;

struct Scene {
    scene: RgbdScene,
    camera_from_object: Isometry3<f64>,
    object_from_marker: Isometry3<f64>,
}

/// A cracker box 0.6 m away, turned 20 degrees, a 4x4 marker on its front.
fn scene() -> Scene {
    let kind = SimObjectKind::CrackerBox;
    let camera_from_object = Isometry3::from_parts(
        Translation3::new(0.03, -0.02, 0.6),
        UnitQuaternion::from_euler_angles(1.2, 0.35, 0.2),
    );
    let mut scene = RgbdScene::new(RgbdSceneConfig::vga(3), kind.mesh(), kind.texture(3)).unwrap();
    let pattern = slidetrack_calibration::marker_pattern("DICT_4X4_50", 7).unwrap();
    let decal = MarkerDecal::on_face_seen_at(pattern, 0.05, scene.mesh(), &camera_from_object).unwrap();
    let object_from_marker = decal.object_from_marker;
    scene.set_marker(Some(decal));
    Scene { scene, camera_from_object, object_from_marker }
}

fn config(object_from_marker: &Isometry3<f64>) -> ArucoConfig {
    ArucoConfig {
        dictionary: "DICT_4X4_50".into(),
        marker_id: 7,
        marker_size_m: 0.05,
        marker_from_object: PoseConfig::of(&object_from_marker.inverse()),
        every_nth_frame: 1,
        delay: ArrivalDelay::None,
        masks: true,
        mask_depth_tolerance_m: Some(0.03),
        max_reprojection_error_px: 2.0,
        background: false,
    }
}

fn frame(s: &Scene, k: u64) -> RgbdFrame {
    frame_every(s, k, 33_333_333)
}

/// Frame `k` of frames `period_ns` apart.
fn frame_every(s: &Scene, k: u64, period_ns: u64) -> RgbdFrame {
    let r = s.scene.render(&s.camera_from_object, k);
    RgbdFrame {
        t: TimeNs(k * period_ns),
        sequence: k,
        color: r.color,
        depth: r.depth,
        intrinsics: s.scene.config().intrinsics.clone(),
    }
}

fn model() -> ObjectModel {
    ObjectModel::from_mesh("cracker_box", SimObjectKind::CrackerBox.mesh())
}

#[test]
fn the_object_pose_and_mask_come_from_the_marker() {
    let s = scene();
    let intrinsics = s.scene.config().intrinsics.clone();
    let mut source = ArucoSource::new(config(&s.object_from_marker), &model(), &intrinsics).unwrap();
    let f = frame(&s, 0);
    let got = source.on_rgbd_frame(&f, None).unwrap();
    assert_eq!(got.poses.len(), 1, "{:?}", source.stats());
    let pose = &got.poses[0];
    assert_eq!((pose.frame_t, pose.arrival_t), (f.t, f.t));
    let dp_mm = position_error_m(&pose.value, &s.camera_from_object) * 1000.0;
    let dr_deg = rotation_error_deg(&pose.value, &s.camera_from_object);
    assert!(dp_mm < 5.0 && dr_deg < 2.0, "{dp_mm} mm, {dr_deg} deg");
    // The rendered mask covers the true one.
    let truth = s.scene.render(&s.camera_from_object, 0).mask;
    let mask = &got.masks[0].value;
    let (mut both, mut either) = (0, 0);
    for (i, inside) in truth.iter().enumerate() {
        let m = mask.contains(i as u32 % 640, i as u32 / 640);
        both += usize::from(m && *inside != 0);
        either += usize::from(m || *inside != 0);
    }
    assert!(both as f64 / either as f64 > 0.9, "IoU {both}/{either}");
    // A marker_from_object that is wrong shows in the pose.
    let mut wrong = config(&Isometry3::identity());
    wrong.masks = false;
    let mut source = ArucoSource::new(wrong, &model(), &intrinsics).unwrap();
    let p = source.on_rgbd_frame(&f, None).unwrap().poses[0].value;
    assert!(position_error_m(&p, &s.camera_from_object) > 0.02);
}

#[test]
fn frames_without_the_marker_give_nothing_and_results_wait_for_their_arrival() {
    let mut s = scene();
    let intrinsics = s.scene.config().intrinsics.clone();
    let mut c = config(&s.object_from_marker);
    c.delay = ArrivalDelay::Measured;
    c.every_nth_frame = 2;
    let mut source = ArucoSource::new(c, &model(), &intrinsics).unwrap();
    // Frame 0 is searched; its result took time (well under the 1 s
    // between these frames), so it arrives by frame 1.
    let frame = |s: &Scene, k| frame_every(s, k, 1_000_000_000);
    assert!(source.on_rgbd_frame(&frame(&s, 0), None).unwrap().poses.is_empty());
    let got = source.on_rgbd_frame(&frame(&s, 1), None).unwrap();
    assert_eq!(got.poses.len(), 1);
    assert_eq!(got.poses[0].frame_t, TimeNs(0));
    assert!(got.poses[0].arrival_t > TimeNs(0));
    // Without the marker: searched, counted, nothing delivered.
    s.scene.set_marker(None);
    assert!(source.on_rgbd_frame(&frame(&s, 2), None).unwrap().poses.is_empty());
    assert!(source.on_rgbd_frame(&frame(&s, 3), None).unwrap().poses.is_empty());
    let stats = source.stats();
    assert_eq!((stats.frames_searched, stats.poses, stats.frames_without_marker), (2, 1, 1));
    // on_frame without the images is an error, not a silent nothing.
    assert!(source.on_frame(TimeNs(5), None).is_err());
}

/// In the background, a frame is searched only when the detection thread
/// is free: frames fed faster than it searches are skipped and counted, and
/// every result comes back with its frame's time, after its compute time,
/// with the pose the inline search finds.
#[test]
fn background_detection_skips_frames_while_busy_and_hands_results_over_later() {
    let s = scene();
    let intrinsics = s.scene.config().intrinsics.clone();
    let mut c = config(&s.object_from_marker);
    c.delay = ArrivalDelay::Measured;
    c.background = true;
    let mut source = ArucoSource::new(c, &model(), &intrinsics).unwrap();
    let frames: Vec<RgbdFrame> = (0..6).map(|k| frame(&s, k)).collect();
    let mut poses = Vec::new();
    // Fed at once, the six frames come faster than one search.
    for f in &frames {
        poses.extend(source.on_rgbd_frame(f, None).unwrap().poses);
    }
    let fed = source.stats();
    assert_eq!(fed.frames_searched + fed.skipped_busy, 6, "{fed:?}");
    assert!(fed.skipped_busy >= 1, "{fed:?}");
    // Frames 20 ms apart (real time) collect what was being searched, and
    // start the next search: one search is always in flight.
    for k in 6..20 {
        std::thread::sleep(std::time::Duration::from_millis(20));
        poses.extend(source.on_rgbd_frame(&frame_every(&s, k, 1_000_000_000), None).unwrap().poses);
    }
    let stats = source.stats();
    assert_eq!(poses.len(), stats.frames_searched - 1, "{stats:?}");
    assert!(poses.len() >= 5, "{stats:?}");
    for p in &poses {
        assert!(frames.iter().any(|f| f.t == p.frame_t) || p.frame_t.0 % 1_000_000_000 == 0);
        assert!(p.arrival_t > p.frame_t, "{:?} {:?}", p.frame_t, p.arrival_t);
        let dp_mm = position_error_m(&p.value, &s.camera_from_object) * 1000.0;
        assert!(dp_mm < 5.0, "{dp_mm} mm");
    }
    assert!(source.summary().unwrap().contains("skipped while detection was busy"));
}

/// The marker's two IPPE poses, fed in either order, resolve to the one
/// the depth agrees with: the true one, while the other is tilted the
/// other way (tens of degrees off). Catches a choice by reprojection error
/// alone, which the order swap turns around.
#[test]
fn the_depth_picks_the_true_one_of_the_two_marker_poses() {
    let s = scene();
    let intrinsics = s.scene.config().intrinsics.clone();
    let mut source = ArucoSource::new(config(&s.object_from_marker), &model(), &intrinsics).unwrap();
    let Runner::Inline(measurer) = &mut source.runner else { panic!("inline by default") };
    let f = frame(&s, 0);
    let detections = measurer.detector.detect(&f.color).unwrap();
    let detection = detections.iter().find(|d| d.id == 7).unwrap();
    let [a, b] = marker_pose_candidates(detection, &intrinsics, 0.05).unwrap();
    let true_marker = s.camera_from_object * s.object_from_marker;
    let off = |p: &MarkerPose| rotation_error_deg(&p.camera_from_marker, &true_marker);
    let (good, bad) = if off(&a) < off(&b) { (a, b) } else { (b, a) };
    assert!(off(&good) < 2.0 && off(&bad) > 10.0, "{} and {} deg", off(&good), off(&bad));
    for pair in [[good.clone(), bad.clone()], [bad.clone(), good.clone()]] {
        let picked = measurer.by_depth(pair, &f.depth);
        assert!(off(&picked) < 2.0, "picked {} deg off", off(&picked));
    }
    // Without depth, the first (the smaller reprojection error) stands.
    let no_depth = slidetrack_core::DepthImage::invalid(f.depth.width, f.depth.height, f.depth.scale_m);
    assert_eq!(measurer.by_depth([bad.clone(), good], &no_depth), bad);
}

#[test]
fn bad_configurations_are_refused_with_the_field() {
    let s = scene();
    let intrinsics = s.scene.config().intrinsics.clone();
    type Spoil = fn(&mut ArucoConfig);
    let cases: [(&str, Spoil); 4] = [
        ("marker_size_m", |c| c.marker_size_m = 0.0),
        ("every_nth_frame", |c| c.every_nth_frame = 0),
        ("marker_id", |c| c.marker_id = 50),
        ("marker_from_object", |c| c.marker_from_object.rotation_xyzw = [0.0, 0.0, 0.0, 0.5]),
    ];
    for (field, spoil) in cases {
        let mut c = config(&s.object_from_marker);
        spoil(&mut c);
        let Err(e) = ArucoSource::new(c, &model(), &intrinsics) else { panic!("{field} accepted") };
        assert!(e.to_string().contains(field), "{field}: {e}");
    }
    let mut c = config(&s.object_from_marker);
    c.dictionary = "DICT_9X9".into();
    let Err(e) = ArucoSource::new(c, &model(), &intrinsics) else { panic!("DICT_9X9 accepted") };
    assert!(e.to_string().contains("DICT_9X9"), "{e}");
    let points_only = ObjectModel { mesh: None, ..model() };
    let Err(e) = ArucoSource::new(config(&s.object_from_marker), &points_only, &intrinsics) else {
        panic!("a model without a mesh accepted")
    };
    assert!(e.to_string().contains("no mesh"), "{e}");
}
