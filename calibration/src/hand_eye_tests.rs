use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;

use super::*;

fn truth() -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(0.25, -0.07, 0.12),
        UnitQuaternion::from_euler_angles(0.3, -0.4, 2.6),
    )
}

fn mount() -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(0.05, 0.0, 0.02),
        UnitQuaternion::from_euler_angles(0.0, 1.2, 0.1),
    )
}

fn view(camera_from_target: Isometry3<f64>, err_px: f64) -> TargetView {
    TargetView { camera_from_target, reprojection_error_px: err_px }
}

/// Noise of `sigma_m` / `sigma_rad` per axis on camera_from_target.
fn noisy_views(n: usize, sigma_m: f64, sigma_rad: f64, seed: u64) -> Vec<TargetView> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let exact = truth().inverse() * mount();
    (0..n)
        .map(|_| {
            let mut g = || rng.sample::<f64, _>(StandardNormal);
            let dt = Vector3::new(g(), g(), g()) * sigma_m;
            let dr = Vector3::new(g(), g(), g()) * sigma_rad;
            let noise = Isometry3::from_parts(Translation3::from(dt), UnitQuaternion::from_scaled_axis(dr));
            view(noise * exact, 0.3)
        })
        .collect()
}

#[test]
fn exact_views_give_the_exact_transform_and_zero_spread() {
    let exact = truth().inverse() * mount();
    let views = vec![view(exact, 0.1); 5];
    let c = estimate_hand_from_camera(&mount(), &views, &HandEyeOptions::default()).unwrap();
    let (mm, deg) = pose_difference(&c.hand_from_camera(), &truth());
    assert!(mm < 1e-9 && deg < 1e-6, "{mm} mm, {deg} deg");
    assert!(c.translation_spread_mm < 1e-9 && c.rotation_spread_deg < 1e-6);
    let (mm, deg) = pose_difference(&c.placement().hand_from_camera().unwrap(), &truth());
    assert!(mm < 1e-9 && deg < 1e-6, "placement: {mm} mm, {deg} deg");
}

#[test]
fn noise_averages_out_and_the_standard_error_matches_the_spread() {
    let views = noisy_views(400, 0.002, 0.01, 3);
    let c = estimate_hand_from_camera(&mount(), &views, &HandEyeOptions::default()).unwrap();
    let (mm, deg) = pose_difference(&c.hand_from_camera(), &truth());
    assert_eq!(c.frames_used, 400);
    // Standard error of the mean of 400 frames: about spread / 20.
    assert!(mm < 4.0 * c.translation_std_error_mm.max(0.05), "{mm} mm vs se {}", c.translation_std_error_mm);
    assert!(deg < 4.0 * c.rotation_std_error_deg, "{deg} deg vs se {}", c.rotation_std_error_deg);
    let ratio = c.translation_spread_mm / c.translation_std_error_mm;
    assert!((ratio - 20.0).abs() < 1.0, "spread/se = {ratio}");
    // 0.01 rad per axis: spread about sqrt(3) * 0.573 deg.
    assert!(
        (c.rotation_spread_deg - 3f64.sqrt() * 0.01f64.to_degrees()).abs() < 0.1,
        "{}",
        c.rotation_spread_deg
    );
}

#[test]
fn a_flipped_frame_and_a_badly_reprojected_frame_are_dropped() {
    let mut views = noisy_views(20, 0.0005, 0.002, 4);
    let exact = truth().inverse() * mount();
    let flip = UnitQuaternion::from_euler_angles(0.5, 0.0, 0.0);
    views.push(view(Isometry3::from_parts(exact.translation, flip * exact.rotation), 0.4));
    views.push(view(Isometry3::translation(0.1, 0.0, 0.0) * exact, 9.0));
    let c = estimate_hand_from_camera(&mount(), &views, &HandEyeOptions::default()).unwrap();
    assert_eq!((c.frames_used, c.frames_rejected_outlier, c.frames_rejected_reprojection), (20, 1, 1));
    let (mm, deg) = pose_difference(&c.hand_from_camera(), &truth());
    assert!(mm < 0.5 && deg < 0.1, "{mm} mm, {deg} deg");
}

#[test]
fn too_few_frames_is_a_typed_error() {
    let e = estimate_hand_from_camera(&mount(), &noisy_views(2, 0.0, 0.0, 1), &HandEyeOptions::default());
    assert_eq!(e.unwrap_err(), HandEyeError::TooFewFrames { usable: 2, needed: 3, total: 2 });
}

#[test]
fn the_placement_line_parses_back_to_the_same_pose() {
    let views = noisy_views(10, 0.0, 0.0, 1);
    let c = estimate_hand_from_camera(&mount(), &views, &HandEyeOptions::default()).unwrap();
    #[derive(serde::Deserialize)]
    struct Camera {
        placement: CameraPlacement,
    }
    let parsed: Camera = toml::from_str(&c.placement_toml()).unwrap();
    let (mm, deg) = pose_difference(&parsed.placement.hand_from_camera().unwrap(), &truth());
    assert!(mm < 0.01 && deg < 1e-5, "{mm} mm, {deg} deg");
}
