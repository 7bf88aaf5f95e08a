//! The judged check: on the simulated rig with a known, non-default camera
//! placement, a marker fixed to the hand is rendered, detected and its pose
//! turned into `hand_from_camera`, which must match the placement within
//! 2 mm and 0.5 degree.

use nalgebra::{Isometry3, Translation3, UnitQuaternion};
use slidetrack_core::CameraPlacement;
use slidetrack_sim::camera::{ObjectAppearance, SimCameraConfig, SimCameraRenderer};

use crate::hand_eye::{HandEyeOptions, TargetView, estimate_hand_from_camera, pose_difference};
use crate::{Dictionary, MarkerTracker, marker_pattern, marker_pose};

#[test]
fn a_marker_on_the_hand_recovers_a_known_camera_placement_within_2_mm_and_half_a_degree() {
    let placement = CameraPlacement::LookAt {
        position_m: [0.28, 0.06, 0.14],
        look_at_m: [0.08, -0.01, 0.0],
        up_in_hand: [0.1, 0.0, 1.0],
    };
    let config = SimCameraConfig { placement: placement.clone(), ..SimCameraConfig::default() };
    let appearance =
        ObjectAppearance { face_size_m: [0.08, 0.08], marker_size_m: 0.05, ..ObjectAppearance::default() };
    // The target's plate: on the palm side, turned and tilted towards the camera.
    let hand_from_plate = Isometry3::from_parts(
        Translation3::new(0.08, 0.0, 0.0),
        UnitQuaternion::from_euler_angles(0.05, -0.35, 0.3),
    );
    let hand_from_target = hand_from_plate * appearance.object_from_marker();
    let marker = marker_pattern("DICT_6X6_250", 7).unwrap();
    let mut r = SimCameraRenderer::new(config, appearance.clone(), marker, 17).unwrap();
    let mut tracker = MarkerTracker::new(Dictionary::from_name("DICT_6X6_250").unwrap(), 7).unwrap();
    let views: Vec<TargetView> = (0..20u64)
        .map(|k| {
            let image = r.render_image(&hand_from_plate, k);
            tracker.reset();
            let d = tracker.detect(&image).unwrap().expect("hand target seen");
            let p = marker_pose(&d, r.intrinsics(), appearance.marker_size_m).unwrap();
            TargetView {
                camera_from_target: p.camera_from_marker,
                reprojection_error_px: p.reprojection_error_px,
            }
        })
        .collect();
    let c = estimate_hand_from_camera(&hand_from_target, &views, &HandEyeOptions::default()).unwrap();
    let truth = placement.hand_from_camera().unwrap();
    let (mm, deg) = pose_difference(&c.hand_from_camera(), &truth);
    println!(
        "calibrate hand (sim, library): error {mm:.3} mm, {deg:.4} deg; frames {} ; se {:.3} mm {:.4} deg; spread {:.3} mm {:.4} deg",
        c.frames_used,
        c.translation_std_error_mm,
        c.rotation_std_error_deg,
        c.translation_spread_mm,
        c.rotation_spread_deg
    );
    assert!(mm < 2.0, "translation error {mm:.3} mm");
    assert!(deg < 0.5, "rotation error {deg:.4} deg");
}
