//! End-to-end checks on the simulated camera: render the marker at a known
//! pose, detect it, recover the pose and the sliding position.

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use slidetrack_sim::camera::{ObjectAppearance, SimCameraConfig, SimCameraRenderer};

use crate::{Dictionary, MarkerTracker, SlidingAxis, marker_pattern, marker_pose};

fn renderer() -> SimCameraRenderer {
    let marker = marker_pattern("DICT_6X6_250", 7).unwrap();
    SimCameraRenderer::new(SimCameraConfig::default(), ObjectAppearance::default(), marker, 11).unwrap()
}

/// The object 0.10 m in front of the palm, `drop_m` down the sliding axis, slightly turned.
fn hand_from_object(drop_m: f64, yaw_rad: f64, pitch_rad: f64) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(0.10, 0.003, -drop_m),
        UnitQuaternion::from_euler_angles(0.0, pitch_rad, yaw_rad),
    )
}

#[test]
fn a_rendered_marker_is_detected_and_its_pose_recovered_within_a_millimetre() {
    let mut r = renderer();
    let mut tracker = MarkerTracker::new(Dictionary::from_name("DICT_6X6_250").unwrap(), 7).unwrap();
    let size_m = r.appearance().marker_size_m;
    for (k, (drop_m, yaw, pitch)) in
        [(0.0, 0.0, 0.0), (0.02, 0.15, -0.1), (0.035, -0.2, 0.12)].into_iter().enumerate()
    {
        let pose = hand_from_object(drop_m, yaw, pitch);
        let image = r.render_image(&pose, k as u64);
        tracker.reset();
        let detection = tracker.detect(&image).unwrap().expect("marker found");
        let estimate = marker_pose(&detection, r.intrinsics(), size_m).unwrap();
        let truth = r.camera_from_marker(&pose);
        let position_error_m =
            (estimate.camera_from_marker.translation.vector - truth.translation.vector).norm();
        let angle_error_rad = estimate.camera_from_marker.rotation.angle_to(&truth.rotation);
        assert!(position_error_m < 1e-3, "pose {k}: position error {:.3} mm", position_error_m * 1e3);
        assert!(angle_error_rad < 0.03, "pose {k}: rotation error {angle_error_rad:.4} rad");
        assert!(estimate.reprojection_error_px < 0.5, "pose {k}: {} px", estimate.reprojection_error_px);
    }
}

#[test]
fn the_sliding_position_follows_the_truth_over_a_five_centimetre_slide() {
    let mut r = renderer();
    let mut tracker = MarkerTracker::new(Dictionary::from_name("DICT_6X6_250").unwrap(), 7).unwrap();
    let axis = SlidingAxis::new(*r.hand_from_camera(), Vector3::new(0.0, 0.0, -1.0)).unwrap();
    let mut projector = axis.projector();
    let size_m = r.appearance().marker_size_m;
    let mut worst_m: f64 = 0.0;
    for k in 0..=25u64 {
        let drop_m = 0.05 * k as f64 / 25.0;
        let image = r.render_image(&hand_from_object(drop_m, 0.0, 0.0), k);
        let detection = tracker.detect(&image).unwrap().expect("marker found");
        let pose = marker_pose(&detection, r.intrinsics(), size_m).unwrap();
        let p_m = projector.project(&pose.camera_from_marker.translation.vector.into()).unwrap();
        worst_m = worst_m.max((p_m - drop_m).abs());
    }
    assert!(worst_m < 0.5e-3, "worst sliding error {:.3} mm", worst_m * 1e3);
    let (roi_hits, full_searches) = tracker.counts();
    assert_eq!((roi_hits, full_searches), (25, 1), "tracked in the region of interest after the first frame");
}

#[test]
fn markers_of_several_dictionaries_rendered_by_the_simulator_decode_to_their_ids() {
    let config =
        SimCameraConfig { pixel_format: slidetrack_core::PixelFormat::Rgb8, ..SimCameraConfig::default() };
    for (name, id) in
        [("DICT_4X4_50", 3), ("DICT_5X5_100", 42), ("DICT_ARUCO_ORIGINAL", 300), ("DICT_APRILTAG_36h11", 11)]
    {
        let marker = marker_pattern(name, id).unwrap();
        let mut r = SimCameraRenderer::new(config.clone(), ObjectAppearance::default(), marker, 5).unwrap();
        let image = r.render_image(&hand_from_object(0.01, 0.1, 0.0), 0);
        let found =
            crate::MarkerDetector::new(Dictionary::from_name(name).unwrap()).unwrap().detect(&image).unwrap();
        assert_eq!(found.iter().map(|d| d.id).collect::<Vec<_>>(), [id], "{name}");
    }
}
