use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use slidetrack_core::{
    BadMarkerPattern, CameraPlacement, Image, MarkerPattern, PixelFormat, PlacementError, TimeNs,
};

use super::raster::UndistortionMap;
use super::*;

/// A 6x6 pattern with a recognisable layout (not from any dictionary).
fn pattern() -> MarkerPattern {
    let bits = (0..36).map(|k| u8::from((k * 7 + k / 6) % 3 == 0)).collect();
    MarkerPattern { dictionary: "TEST_6X6".into(), id: 7, cells: 6, bits }
}

/// The object 0.10 m in front of the palm, face towards the camera.
fn hand_from_object(drop_m: f64) -> Isometry3<f64> {
    Isometry3::from_parts(Translation3::new(0.10, 0.0, -drop_m), UnitQuaternion::identity())
}

fn renderer(config: SimCameraConfig, seed: u64) -> SimCameraRenderer {
    SimCameraRenderer::new(config, ObjectAppearance::default(), pattern(), seed).unwrap()
}

fn gray_at(image: &Image, u: f64, v: f64) -> f64 {
    let channels = image.format.channels();
    let idx = (v.round() as usize * image.width as usize + u.round() as usize) * channels;
    image.data[idx..idx + channels].iter().map(|&b| f64::from(b)).sum::<f64>() / channels as f64
}

#[test]
fn undistortion_map_is_consistent_with_project() {
    let config = SimCameraConfig::default();
    let c = &config.intrinsics;
    let map = UndistortionMap::new(c);
    for &(i, j) in &[(0, 0), (640, 480), (320, 240), (17, 401), (600, 3)] {
        let [x, y] = map.corner(i, j);
        let (u, v) = c.project([x, y, 1.0]).unwrap();
        assert!(
            (u - (i as f64 - 0.5)).abs() < 1e-3 && (v - (j as f64 - 0.5)).abs() < 1e-3,
            "{i},{j} -> {u},{v}"
        );
    }
    // Inside a pixel the map is interpolated; the centre ray must project back onto the centre.
    let [x, y] = map.pixel_centre(5, 7);
    let (u, v) = c.project([x, y, 1.0]).unwrap();
    assert!((u - 5.0).abs() < 1e-3 && (v - 7.0).abs() < 1e-3, "{u},{v}");
}

#[test]
fn look_at_points_the_optical_axis_at_the_target_with_hand_up_as_image_up() {
    let config = SimCameraConfig::default();
    let hand_from_camera = config.hand_from_camera().unwrap();
    let camera_from_hand = hand_from_camera.inverse();
    let target = camera_from_hand * nalgebra::Point3::new(0.10, 0.0, 0.0);
    assert!(target.x.abs() < 1e-12 && target.y.abs() < 1e-12 && target.z > 0.2);
    let above = camera_from_hand * nalgebra::Point3::new(0.10, 0.0, 0.02);
    let left = camera_from_hand * nalgebra::Point3::new(0.10, 0.02, 0.0);
    assert!(above.y < target.y, "hand +z is image up");
    assert!(left.x > target.x, "hand +y (left of the hand) is image right, seen from the front");
}

#[test]
fn rendering_is_deterministic_for_a_seed() {
    let mut a = renderer(SimCameraConfig::default(), 42);
    let mut b = renderer(SimCameraConfig::default(), 42);
    let mut c = renderer(SimCameraConfig::default(), 43);
    let pose = hand_from_object(0.01);
    let fa = a.render(&pose, TimeNs(0), 5);
    let fb = b.render(&pose, TimeNs(0), 5);
    let fc = c.render(&pose, TimeNs(0), 5);
    assert_eq!(fa.pixels, fb.pixels);
    assert_eq!(fa.encoded, fb.encoded);
    assert_ne!(fa.pixels, fc.pixels, "another seed gives other noise");
    // Frame 5 does not depend on what was rendered before it.
    let _ = a.render(&hand_from_object(0.03), TimeNs(1), 6);
    assert_eq!(a.render(&pose, TimeNs(0), 5).pixels, fa.pixels);
    let encoded = fa.encoded.unwrap();
    assert_eq!(encoded.format, "jpeg");
    assert_eq!(&encoded.bytes[..2], &[0xFF, 0xD8], "JPEG start of image");
}

#[test]
fn noise_has_the_configured_strength() {
    let config = SimCameraConfig { noise_std_gray: 3.0, ..SimCameraConfig::default() };
    let mut r = renderer(config, 1);
    let pose = hand_from_object(0.0);
    let a = r.render_image(&pose, 1);
    let b = r.render_image(&pose, 2);
    // Difference of two frames of a static scene: std = sqrt(2) * 3 gray levels.
    let diffs: Vec<f64> = a.data.iter().zip(&b.data).map(|(&x, &y)| f64::from(x) - f64::from(y)).collect();
    let var = diffs.iter().map(|d| d * d).sum::<f64>() / diffs.len() as f64;
    let std = var.sqrt() / 2f64.sqrt();
    assert!((std - 3.0).abs() < 0.2, "noise std {std}");
}

#[test]
fn marker_cells_land_where_the_intrinsics_project_them_and_edges_are_blurred() {
    let config = SimCameraConfig { noise_std_gray: 0.0, blur_sigma_px: 1.0, ..SimCameraConfig::default() };
    let mut r = renderer(config, 3);
    let pose = hand_from_object(0.02);
    let image = r.render_image(&pose, 0);
    let camera_from_marker = r.camera_from_marker(&pose);
    let intrinsics = r.intrinsics().clone();
    let marker = pattern();
    let cell_m = r.appearance().cell_size_m(marker.cells);
    let half = r.appearance().marker_size_m / 2.0;
    let mut transitions = 0;
    for row in 0..8usize {
        for col in 0..8usize {
            // Cell centre in the marker frame: x right, y up from the marker centre.
            let x = -half + (col as f64 + 0.5) * cell_m;
            let y = half - (row as f64 + 0.5) * cell_m;
            let p = camera_from_marker * nalgebra::Point3::new(x, y, 0.0);
            let (u, v) = intrinsics.project([p.x, p.y, p.z]).unwrap();
            let white = row >= 1 && col >= 1 && marker.is_white(row - 1, col - 1);
            let g = gray_at(&image, u, v);
            if white {
                assert!(g > 150.0, "cell ({row},{col}) should be white: {g}");
            } else {
                assert!(g < 60.0, "cell ({row},{col}) should be black: {g}");
            }
            // Half a cell to the right, on the edge between two cells of different colour.
            let q = camera_from_marker * nalgebra::Point3::new(x + cell_m / 2.0, y, 0.0);
            let (ue, ve) = intrinsics.project([q.x, q.y, q.z]).unwrap();
            let next_white =
                (1..=6).contains(&row) && (1..=6).contains(&(col + 1)) && marker.is_white(row - 1, col);
            if col < 7 && white != next_white {
                let e = gray_at(&image, ue, ve);
                assert!(e > 70.0 && e < 190.0, "edge after cell ({row},{col}) should be mid-gray: {e}");
                transitions += 1;
            }
        }
    }
    assert!(transitions > 5);
}

#[test]
fn gray_and_rgb_frames_have_the_right_layout() {
    for format in [PixelFormat::Gray8, PixelFormat::Rgb8] {
        let config = SimCameraConfig { pixel_format: format, ..SimCameraConfig::default() };
        let mut r = renderer(config, 9);
        let frame = r.render(&hand_from_object(0.0), TimeNs(33), 1);
        let pixels = frame.pixels.unwrap();
        assert_eq!(pixels.format, format);
        assert_eq!(pixels.data.len(), 640 * 480 * format.channels());
        assert_eq!((frame.t, frame.sequence), (TimeNs(33), 1));
    }
}

#[test]
fn an_object_out_of_view_or_behind_the_camera_leaves_the_background() {
    let config = SimCameraConfig { noise_std_gray: 0.0, ..SimCameraConfig::default() };
    let mut r = renderer(config, 2);
    let empty = r.render_image(&hand_from_object(5.0), 0);
    let behind = Isometry3::from_parts(Translation3::new(0.6, 0.0, 0.2), UnitQuaternion::identity());
    assert_eq!(r.render_image(&behind, 0), empty);
    // Facing away from the camera: the face is not drawn.
    let turned = Isometry3::from_parts(
        Translation3::new(0.10, 0.0, 0.0),
        UnitQuaternion::from_axis_angle(&Vector3::z_axis(), std::f64::consts::PI),
    );
    assert_eq!(r.render_image(&turned, 0), empty);
    assert_ne!(r.render_image(&hand_from_object(0.0), 0), empty);
}

#[test]
fn chessboard_squares_alternate_where_projected() {
    let config = SimCameraConfig { noise_std_gray: 0.0, ..SimCameraConfig::default() };
    let r = renderer(config, 4);
    let board = Chessboard::default();
    // Board 0.4 m in front of the camera, facing it (board z along the optical axis).
    let camera_from_board =
        Isometry3::from_parts(Translation3::new(-0.1, -0.06, 0.4), UnitQuaternion::identity());
    let image = r.render_board(&board, &camera_from_board);
    let s = board.square_size_m;
    for (qx, qy, black) in
        [(1.0, 1.0, true), (2.0, 1.0, false), (2.0, 2.0, true), (0.0, 0.0, true), (9.0, 6.0, false)]
    {
        let p = camera_from_board * nalgebra::Point3::new((qx - 0.5) * s, (qy - 0.5) * s, 0.0);
        let (u, v) = r.intrinsics().project([p.x, p.y, p.z]).unwrap();
        let g = gray_at(&image, u, v);
        assert_eq!(g < 100.0, black, "square ({qx},{qy}) at ({u:.0},{v:.0}) is {g}");
    }
    assert_eq!(board.corners_in_board().len(), 54);
    assert_eq!(board.corners_in_board()[10], [0.025, 0.025, 0.0]);
}

#[test]
fn bad_inputs_are_reported_with_their_values() {
    let bad_bits = MarkerPattern { bits: vec![0; 35], ..pattern() };
    let err = SimCameraRenderer::new(SimCameraConfig::default(), ObjectAppearance::default(), bad_bits, 0)
        .err()
        .unwrap();
    assert!(matches!(err, SimCameraError::Marker(BadMarkerPattern { bits_len: 35, cells: 6, .. })), "{err}");
    let placement = CameraPlacement::LookAt {
        position_m: [0.0; 3],
        look_at_m: [0.0, 0.0, 1.0],
        up_in_hand: [0.0, 0.0, 1.0],
    };
    let config = SimCameraConfig { placement, ..SimCameraConfig::default() };
    assert!(matches!(
        config.validate(),
        Err(SimCameraError::Placement(PlacementError::DegenerateLookAt { .. }))
    ));
    let config = SimCameraConfig { jpeg_quality: 0, ..SimCameraConfig::default() };
    assert!(config.validate().unwrap_err().to_string().contains("jpeg_quality"));
}

#[test]
fn config_reads_from_toml_and_rejects_unknown_fields() {
    let text = r#"
        fps = 60.0
        pixel_format = "Rgb8"
        placement = { kind = "pose", translation_m = [0.3, 0.0, 0.1], quaternion_xyzw = [-0.5, -0.5, 0.5, 0.5] }
        [background]
        texture_seed = 7
    "#;
    let config: SimCameraConfig = toml::from_str(text).unwrap();
    assert_eq!(config.fps, 60.0);
    assert_eq!(config.pixel_format, PixelFormat::Rgb8);
    assert_eq!(config.background.texture_seed, 7);
    assert_eq!(config.background.feature_size_m, BackgroundConfig::default().feature_size_m);
    let hand_from_camera = config.hand_from_camera().unwrap();
    // That quaternion turns the camera's z (forward) onto the hand's -x.
    let forward = hand_from_camera.rotation * Vector3::z();
    assert!((forward - Vector3::new(-1.0, 0.0, 0.0)).norm() < 1e-9, "{forward}");
    assert!(toml::from_str::<SimCameraConfig>("frame_rate = 30.0").is_err());
    let look_at = "placement = { kind = \"look_at\", position_m = [0.3, 0, 0.1], look_at_m = [0.1, 0, 0], up_in_hand = [0, 0, 1], extra = 1 }";
    assert!(toml::from_str::<SimCameraConfig>(look_at).is_err());
}

#[test]
fn the_block_renderer_matches_rendering_every_pixel() {
    for format in [PixelFormat::Gray8, PixelFormat::Rgb8] {
        let config = SimCameraConfig { pixel_format: format, ..SimCameraConfig::default() };
        let mut fast = renderer(config.clone(), 8);
        let mut reference = renderer(config, 8);
        reference.set_exhaustive(true);
        let tilted = Isometry3::from_parts(
            Translation3::new(0.11, 0.004, -0.013),
            UnitQuaternion::from_euler_angles(0.05, -0.2, 0.3),
        );
        for (k, pose) in [hand_from_object(0.0), tilted].iter().enumerate() {
            let a = fast.render_image(pose, k as u64);
            let b = reference.render_image(pose, k as u64);
            // Only float summation order differs: at most one gray level, rarely.
            let differing = a.data.iter().zip(&b.data).filter(|(x, y)| x != y).count();
            let worst = a.data.iter().zip(&b.data).map(|(x, y)| x.abs_diff(*y)).max().unwrap();
            assert!(
                worst <= 1 && differing * 1000 < a.data.len(),
                "{format:?} pose {k}: {differing} differ, worst {worst}"
            );
        }
    }
}

#[test]
fn the_renderer_can_move_to_the_rig_thread() {
    fn assert_send<T: Send>() {}
    assert_send::<SimCameraRenderer>();
}

#[test]
fn drawing_on_two_threads_gives_the_same_frames_as_on_one() {
    // Catches a band boundary that drops, repeats or misplaces rows, a band
    // that blurs across its edge into rows it did not render, and noise read
    // at the wrong offset in the lower band.
    for format in [PixelFormat::Gray8, PixelFormat::Rgb8] {
        let config = SimCameraConfig { pixel_format: format, ..SimCameraConfig::default() };
        let mut one = renderer(config.clone(), 3);
        let mut two = renderer(config, 3);
        one.set_two_threads(false);
        two.set_two_threads(true);
        let tilted = |k: f64| {
            Isometry3::from_parts(
                Translation3::new(0.10 + 0.01 * k, 0.003 * k, -0.01 * k),
                UnitQuaternion::from_euler_angles(0.05 * k, -0.1 * k, 0.15 * k),
            )
        };
        let poses = [hand_from_object(0.0), hand_from_object(0.02), tilted(1.0), tilted(-1.5), tilted(2.0)];
        for (k, pose) in poses.iter().enumerate() {
            let (a, b) = (one.render_image(pose, k as u64), two.render_image(pose, k as u64));
            assert!(a.data == b.data, "{format:?} pose {k}: the frames differ");
        }
        let board = Chessboard::default();
        let camera_from_board = Isometry3::from_parts(
            Translation3::new(-0.1, -0.06, 0.45),
            UnitQuaternion::from_euler_angles(0.3, -0.2, 0.1),
        );
        let (a, b) =
            (one.render_board(&board, &camera_from_board), two.render_board(&board, &camera_from_board));
        assert!(a.data == b.data, "{format:?}: the boards differ");
    }
}
