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

/// `noise` applied to a flat wall at `z_m` seen by a 640x480 camera with a
/// 554.3 px focal length: the millimetres, with standard normals and uniforms
/// from a fixed generator.
fn wall_depth(noise: &DepthNoise, z_m: f32) -> Vec<u16> {
    let (w, h) = (640, 480);
    let mut state = 7u64;
    let mut uniform = || {
        state = slidetrack_render::splitmix64(state);
        ((state >> 40) as f32 + 0.5) / (1u64 << 24) as f32
    };
    let normals: Vec<f32> = (0..w * h)
        .map(|_| (-2.0 * uniform().ln()).sqrt() * (std::f32::consts::TAU * uniform()).cos())
        .collect();
    let uniforms: Vec<f32> = (0..w * h).map(|_| uniform()).collect();
    let (depth, mask, cos) = (vec![z_m; w * h], vec![0u8; w * h], vec![1.0f32; w * h]);
    let clean =
        depth_noise::CleanDepth { size: (w, h), fx: 554.3, depth_m: &depth, mask: &mask, normal_cos: &cos };
    noise.apply(&clean, &normals, &uniforms).data
}

/// Correlation of horizontally neighbouring errors and the RMS error (mm).
fn neighbour_correlation_and_rms(mm: &[u16], z_mm: f64) -> (f64, f64) {
    let e: Vec<f64> = mm.iter().map(|v| f64::from(*v) - z_mm).collect();
    let pairs: Vec<(f64, f64)> = e.chunks(640).flat_map(|row| row.windows(2).map(|p| (p[0], p[1]))).collect();
    let var = e.iter().map(|x| x * x).sum::<f64>() / e.len() as f64;
    let cov = pairs.iter().map(|(a, b)| a * b).sum::<f64>() / pairs.len() as f64;
    (cov / var, var.sqrt())
}

#[test]
fn simulated_depth_is_quantised_in_disparity_and_correlated_between_neighbours() {
    let noise = DepthNoise { dropout: 0.0, ..DepthNoise::default() };
    let mm = wall_depth(&noise, 1.3);
    assert!(mm.iter().all(|v| *v > 0), "no dropouts asked for");
    // Every value is a disparity step f b / (k step), rounded to millimetres.
    let fb = 554.3 * noise.baseline_m;
    for v in &mm {
        let k = (fb / (f64::from(*v) / 1000.0) / noise.disparity_step_px).round();
        let level = (fb / (k * noise.disparity_step_px) * 1000.0).round();
        assert_eq!(f64::from(*v), level, "{v} mm is not a disparity level");
    }
    let levels: std::collections::BTreeSet<u16> = mm.iter().copied().collect();
    assert!(levels.len() < 12, "{levels:?}");
    // The spread is the measured axial noise at 1.3 m (2.7 mm) plus the
    // steps' rounding (4.9 mm apart: 1.4 mm RMS), and neighbours share it.
    let (rho, rms) = neighbour_correlation_and_rms(&mm, 1300.0);
    let expected = (2.74f64.powi(2) + 4.9f64.powi(2) / 12.0).sqrt();
    assert!((rms - expected).abs() < 0.35, "RMS {rms} mm vs {expected}");
    assert!(rho > 0.6, "neighbour correlation {rho}");

    // The earlier model: independent per pixel, every millimetre possible.
    let independent = DepthNoise { correlation_px: 1, disparity_step_px: 0.0, ..noise };
    let mm = wall_depth(&independent, 1.3);
    let (rho, rms) = neighbour_correlation_and_rms(&mm, 1300.0);
    assert!(rho.abs() < 0.02, "neighbour correlation {rho}");
    assert!((rms - 2.74).abs() < 0.1, "RMS {rms} mm");
}
