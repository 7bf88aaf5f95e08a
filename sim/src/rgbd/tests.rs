//! The simulated RGB-D camera against geometry it must reproduce.

use slidetrack_core::CameraIntrinsics;
use slidetrack_render::TriangleMesh;

use super::*;

fn small_camera() -> CameraIntrinsics {
    CameraIntrinsics {
        width: 160,
        height: 120,
        fx: 140.0,
        fy: 140.0,
        cx: 79.5,
        cy: 59.5,
        distortion: [0.0; 5],
    }
}

#[test]
fn the_fast_motion_respects_its_peak_speeds_and_its_velocity_is_exact() {
    let config = FastMotionConfig { duration_s: 6.0, seed: 4, ..FastMotionConfig::default() };
    let motion = FastMotion::new(&config);
    let (mut top_v, mut top_w) = (0.0f64, 0.0f64);
    for i in 0..600 {
        let t = i as f64 * 0.01;
        let (pose, v, w) = motion.truth(t);
        top_v = top_v.max(v.norm());
        top_w = top_w.max(w.norm());
        // The position stays in view, in front of the camera.
        assert!(pose.translation.z > 0.5 && pose.translation.x.abs() < 0.3);
        // ṗ and ω against central differences.
        let h = 1e-4;
        let (a, _, _) = motion.truth(t + h);
        let (b, _, _) = motion.truth((t - h).max(0.0));
        if t > h {
            let fd_v = (a.translation.vector - b.translation.vector) / (2.0 * h);
            assert!((fd_v - v).norm() < 1e-4, "{t}");
            let fd_w = (a.rotation * b.rotation.inverse()).scaled_axis() / (2.0 * h);
            assert!((fd_w - w).norm() < 1e-3, "{t}: {fd_w:?} vs {w:?}");
        }
    }
    assert!(top_v <= 0.6 + 1e-9 && top_v > 0.45, "{top_v}");
    assert!((top_w.to_degrees() - 270.0).abs() < 3.0, "{}", top_w.to_degrees());
}

#[test]
fn rendered_frames_show_the_object_with_noisy_depth_and_a_mask() {
    let mut config = FastSequenceConfig::new(SimObjectKind::CrackerBox, 1.0, 3);
    config.scene.intrinsics = small_camera();
    let seq = FastSequence::new(config).unwrap();
    assert_eq!(seq.len(), 30);
    let (frame, mask, truth) = seq.frame(5);
    assert_eq!(frame.color.data.len(), 160 * 120 * 3);
    let on_object = mask.iter().filter(|m| **m == 255).count();
    assert!(on_object > 200, "{on_object}");
    // Depth on the object is near the object's distance, with some invalid pixels.
    let z = truth.camera_from_object.translation.z;
    let mut valid = 0;
    for (i, m) in mask.iter().enumerate() {
        if *m == 255 && frame.depth.data[i] != 0 {
            valid += 1;
            let d = f64::from(frame.depth.data[i]) * frame.depth.scale_m;
            assert!((d - z).abs() < 0.2, "{d} vs {z}");
        }
    }
    assert!(valid > on_object / 2 && valid < on_object, "{valid} of {on_object}");
    // Deterministic: the same frame renders to the same bytes.
    let (again, _, _) = seq.frame(5);
    assert_eq!(again.color.data, frame.color.data);
    assert_eq!(again.depth.data, frame.depth.data);
    // The next frame differs (the object moves fast).
    let (next, _, _) = seq.frame(6);
    assert_ne!(next.color.data, frame.color.data);
}

#[test]
fn bad_scene_settings_are_refused() {
    let mut config = RgbdSceneConfig::vga(1);
    config.intrinsics.fx = 0.0;
    assert!(
        RgbdScene::new(config, TriangleMesh::cuboid([0.1; 3]), SimObjectKind::SoupCan.texture(1)).is_err()
    );
    let mut config = FastSequenceConfig::new(SimObjectKind::SoupCan, 1.0, 1);
    config.fps = 0.0;
    assert!(FastSequence::new(config).is_err());
    assert_eq!(SimObjectKind::from_name("soup_can"), Some(SimObjectKind::SoupCan));
    assert!(SimObjectKind::from_name("anvil").is_none());
}
