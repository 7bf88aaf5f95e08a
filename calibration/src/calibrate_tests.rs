//! Calibration recovers the simulator's intrinsics from rendered boards,
//! and OpenCV's published result from its own chessboard photos.

use std::path::PathBuf;

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use slidetrack_sim::SimBoardCamera;
use slidetrack_sim::camera::{Chessboard, SimCameraConfig};

use super::*;
use crate::calibrate_live::{LiveOptions, capture_views};

fn testdata(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/testdata").join(rel)
}

/// Views of the sample board (9x6, 25 mm) at varied poses in front of the simulated camera.
fn rendered_views(n: usize) -> (Vec<PatternView>, CameraIntrinsics) {
    let camera = SimBoardCamera::new(SimCameraConfig::default(), Chessboard::default(), 3).unwrap();
    let intrinsics = slidetrack_core::Camera::intrinsics(&camera).clone();
    let mut finder = PatternFinder::new("chessboard:9x6:0.025".parse().unwrap()).unwrap();
    let renderer_views: Vec<PatternView> = (0..n as u64 * 3)
        .filter_map(|k| {
            let pose = camera.camera_from_board(k * 7);
            let image = camera_render(&camera, &pose);
            finder.find_in_image(&image).unwrap()
        })
        .take(n)
        .collect();
    (renderer_views, intrinsics)
}

fn camera_render(camera: &SimBoardCamera, pose: &Isometry3<f64>) -> Image {
    camera.render(pose)
}

#[test]
fn rendered_board_views_give_back_the_simulated_intrinsics() {
    let (views, truth) = rendered_views(15);
    assert_eq!(views.len(), 15, "the board is found in rendered views");
    let c = calibrate(&views, truth.width, truth.height, CalibrateOptions::default()).unwrap();
    let k = &c.intrinsics;
    let rel = |a: f64, b: f64| (a - b).abs() / b;
    assert!(rel(k.fx, truth.fx) < 0.005 && rel(k.fy, truth.fy) < 0.005, "{k:?} vs {truth:?}");
    assert!((k.cx - truth.cx).abs() < 2.0 && (k.cy - truth.cy).abs() < 2.0, "{k:?} vs {truth:?}");
    assert!(
        (k.distortion[0] - truth.distortion[0]).abs() < 0.02,
        "k1 {} vs {}",
        k.distortion[0],
        truth.distortion[0]
    );
    assert!(c.rms_px < 0.3, "RMS {} px", c.rms_px);
}

#[test]
fn opencvs_chessboard_photos_give_opencvs_result() {
    let mut finder = PatternFinder::new("chessboard:9x6:0.025".parse().unwrap()).unwrap();
    let mut views = Vec::new();
    for n in [1, 2, 3, 4, 5, 6, 7, 8, 9, 11, 12, 13, 14] {
        let gray = read_gray(&testdata(&format!("calib/opencv_left/left{n:02}.jpg"))).unwrap();
        views.push(finder.find(gray.mat()).unwrap().unwrap_or_else(|| panic!("left{n:02}: no board")));
    }
    // The refined corners match OpenCV's (reference computed by OpenCV's Python bindings).
    let reference: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(testdata("calib/opencv_left_corners.json")).unwrap())
            .unwrap();
    for (view, n) in views.iter().zip([1, 2, 3, 4, 5, 6, 7, 8, 9, 11, 12, 13, 14]) {
        let corners = reference["corners_px_row_major_9x6"][format!("left{n:02}.jpg")].as_array().unwrap();
        for (p, r) in view.image_points.iter().zip(corners) {
            let (x, y) = (r[0].as_f64().unwrap(), r[1].as_f64().unwrap());
            assert!(
                (f64::from(p[0]) - x).abs() < 0.01 && (f64::from(p[1]) - y).abs() < 0.01,
                "left{n:02}: {p:?} vs {x}, {y}"
            );
        }
    }
    let c = calibrate(&views, 640, 480, CalibrateOptions::default()).unwrap();
    // cv2.calibrateCamera, flags 0: RMS 0.40877 px, fx 536.07, fy 536.02, cx 342.37, cy 235.54.
    assert!((c.rms_px - 0.40877).abs() < 0.001, "RMS {}", c.rms_px);
    let k = &c.intrinsics;
    assert!((k.fx - 536.074).abs() / 536.074 < 0.001 && (k.fy - 536.017).abs() / 536.017 < 0.001, "{k:?}");
    assert!((k.cx - 342.37).abs() < 0.5 && (k.cy - 235.54).abs() < 0.5, "{k:?}");
    assert_eq!(c.per_view_rms_px.len(), 13);
    assert!(
        (c.per_view_rms_px[1] - 1.2201).abs() < 0.01,
        "left02 is the outlier view: {:?}",
        c.per_view_rms_px
    );
}

#[test]
fn an_image_without_the_pattern_gives_none_and_few_views_are_refused() {
    let mut finder = PatternFinder::new("chessboard:9x6:0.025".parse().unwrap()).unwrap();
    let gray = read_gray(&testdata("aruco/singlemarkersoriginal.jpg")).unwrap();
    assert_eq!(finder.find(gray.mat()).unwrap(), None);
    let err = calibrate(&[], 640, 480, CalibrateOptions::default()).unwrap_err();
    assert!(matches!(err, CalibrationError::TooFewViews { found: 0, .. }), "{err}");
    let err = read_gray(Path::new("/nonexistent.png")).unwrap_err();
    assert!(err.to_string().contains("/nonexistent.png"), "{err}");
}

#[test]
fn live_capture_from_the_simulated_board_camera_keeps_spread_views_and_calibrates() {
    let mut camera = SimBoardCamera::new(SimCameraConfig::default(), Chessboard::default(), 9).unwrap();
    let truth = slidetrack_core::Camera::intrinsics(&camera).clone();
    let mut finder = PatternFinder::new("chessboard:9x6:0.025".parse().unwrap()).unwrap();
    let options = LiveOptions { views: 12, max_frames: 400, keep_images: true, ..LiveOptions::default() };
    let mut updates = 0;
    let capture = capture_views(&mut camera, &mut finder, &options, &mut |_| updates += 1).unwrap();
    assert_eq!(
        capture.views.len(),
        12,
        "{} frames, {} with the board",
        capture.frames,
        capture.frames_with_pattern
    );
    assert_eq!(updates, capture.frames);
    for (i, a) in capture.placements.iter().enumerate() {
        for b in &capture.placements[..i] {
            assert!(a.distance(b) >= options.min_spread);
        }
    }
    let c = calibrate(&capture.views, capture.width, capture.height, CalibrateOptions::default()).unwrap();
    assert!((c.intrinsics.fx - truth.fx).abs() / truth.fx < 0.01, "{:?}", c.intrinsics);
    // The kept frames, saved as PNG, give the same views back.
    assert_eq!(capture.images.len(), capture.views.len());
    for (png, view) in capture.images.iter().zip(&capture.views) {
        let gray = gray_mat(&crate::codec::decode(png, PixelFormat::Gray8).unwrap()).unwrap();
        assert_eq!((gray.cols(), gray.rows()), (capture.width as i32, capture.height as i32));
        assert_eq!(finder.find(&gray).unwrap().as_ref(), Some(view));
    }
}

#[test]
fn a_board_facing_the_camera_has_no_tilt_and_a_turned_one_has() {
    let camera = SimBoardCamera::new(SimCameraConfig::default(), Chessboard::default(), 1).unwrap();
    let mut finder = PatternFinder::new("chessboard:9x6:0.025".parse().unwrap()).unwrap();
    let at = |rotation: UnitQuaternion<f64>| {
        Isometry3::from_parts(Translation3::new(0.0, 0.0, 0.4), rotation)
            * Translation3::new(-0.1, -0.0625, 0.0)
    };
    let flat = finder.find_in_image(&camera.render(&at(UnitQuaternion::identity()))).unwrap().unwrap();
    let p = crate::calibrate_live::ViewPlacement::of(&flat, 640, 480).unwrap();
    assert!(p.tilt[0].abs() < 0.02 && p.tilt[1].abs() < 0.02, "{p:?}");
    let turned = at(UnitQuaternion::from_axis_angle(&Vector3::y_axis(), 0.5));
    let view = finder.find_in_image(&camera.render(&turned)).unwrap().unwrap();
    let q = crate::calibrate_live::ViewPlacement::of(&view, 640, 480).unwrap();
    assert!(q.tilt[0].abs() > 0.1, "{q:?}");
    assert!(p.distance(&q) > 0.05);
}

/// Views of a flat pattern image (`ppm` px per metre, `margin_px` around it)
/// as a distortion-free camera `k` sees it at the poses of [`SimBoardCamera`],
/// by warping it with the plane's homography `K [r1 r2 t] A`.
fn warped_views(
    pattern: &Mat,
    ppm: f64,
    margin_px: f64,
    centre_m: [f64; 2],
    k: [f64; 4],
    n: u64,
) -> Vec<Mat> {
    use opencv::core::{BORDER_CONSTANT, Scalar};
    let [fx, fy, cx, cy] = k;
    let camera = SimBoardCamera::new(SimCameraConfig::default(), Chessboard::default(), 1).unwrap();
    (0..n)
        .map(|i| {
            // The sim's board poses, re-centred on this pattern's centre.
            let pose = camera.camera_from_board(i * 5)
                * Translation3::new(0.1 - centre_m[0], 0.0625 - centre_m[1], 0.0);
            let r = pose.rotation.to_rotation_matrix();
            let t = pose.translation.vector;
            let rt = nalgebra::Matrix3::from_columns(&[
                r.matrix().column(0).into(),
                r.matrix().column(1).into(),
                t,
            ]);
            let kk = nalgebra::Matrix3::new(fx, 0.0, cx, 0.0, fy, cy, 0.0, 0.0, 1.0);
            let a = nalgebra::Matrix3::new(
                1.0 / ppm,
                0.0,
                -margin_px / ppm,
                0.0,
                1.0 / ppm,
                -margin_px / ppm,
                0.0,
                0.0,
                1.0,
            );
            let h = kk * rt * a;
            let rows: Vec<[f64; 3]> = (0..3).map(|i| [h[(i, 0)], h[(i, 1)], h[(i, 2)]]).collect();
            let h = Mat::from_slice_2d(&rows).unwrap();
            let mut view = Mat::default();
            imgproc::warp_perspective(
                pattern,
                &mut view,
                &h,
                Size::new(640, 480),
                imgproc::INTER_AREA,
                BORDER_CONSTANT,
                Scalar::all(255.0),
            )
            .unwrap();
            view
        })
        .collect()
}

fn calibrate_warped(spec: &str, pattern: &Mat, ppm: f64, margin_px: f64, centre_m: [f64; 2]) -> Calibration {
    let k = [610.0, 605.0, 318.0, 245.0];
    let mut finder = PatternFinder::new(spec.parse().unwrap()).unwrap();
    let views: Vec<PatternView> = warped_views(pattern, ppm, margin_px, centre_m, k, 24)
        .iter()
        .filter_map(|v| finder.find(v).unwrap())
        .collect();
    assert!(views.len() >= 8, "{spec}: the pattern is found in {} of 24 views", views.len());
    let options = CalibrateOptions { zero_tangent: true, fix_k3: true, ..CalibrateOptions::default() };
    let c = calibrate(&views, 640, 480, options).unwrap();
    let i = &c.intrinsics;
    assert!((i.fx - k[0]).abs() / k[0] < 0.01 && (i.fy - k[1]).abs() / k[1] < 0.01, "{spec}: {i:?}");
    assert!((i.cx - k[2]).abs() < 3.0 && (i.cy - k[3]).abs() < 3.0, "{spec}: {i:?}");
    c
}

#[test]
fn charuco_boards_are_found_and_calibrate() {
    // OpenCV's tutorial board: 5x7 squares of 40 mm, 20 mm markers of DICT_6X6_250.
    let mut finder = PatternFinder::new("charuco:5x7:0.04:0.02:DICT_6X6_250".parse().unwrap()).unwrap();
    let photo = read_gray(&testdata("aruco/choriginal.jpg")).unwrap();
    let view = finder.find(photo.mat()).unwrap().expect("corners in OpenCV's ChArUco photo");
    assert!(view.image_points.len() >= 12, "{} corners", view.image_points.len());
    let (ppm, margin) = (2000.0, 40);
    let Some((board, _, _)) = &mut finder.charuco else { panic!("a ChArUco finder") };
    let mut drawn = Mat::default();
    let size = Size::new((0.2 * ppm) as i32 + 2 * margin, (0.28 * ppm) as i32 + 2 * margin);
    aruco::CharucoBoardTrait::draw(board, size, &mut drawn, margin, 1).unwrap();
    calibrate_warped("charuco:5x7:0.04:0.02:DICT_6X6_250", &drawn, ppm, f64::from(margin), [0.1, 0.14]);
}

#[test]
fn asymmetric_circle_grids_are_found_and_calibrate() {
    use opencv::core::{CV_8UC1, Point, Scalar};
    // OpenCV's 4x11 grid with a 20 mm squareSize: rows 20 mm apart, circles 40 mm apart in a row.
    let (ppm, margin, s) = (2000.0, 60.0, 0.02);
    let (w, h) = ((7.0 * s * ppm + 2.0 * margin) as i32, (10.0 * s * ppm + 2.0 * margin) as i32);
    let mut canvas = Mat::new_rows_cols_with_default(h, w, CV_8UC1, Scalar::all(255.0)).unwrap();
    for j in 0..11 {
        for i in 0..4 {
            let x = f64::from(2 * i + j % 2) * s * ppm + margin;
            let y = f64::from(j) * s * ppm + margin;
            let centre = Point::new(x.round() as i32, y.round() as i32);
            imgproc::circle(
                &mut canvas,
                centre,
                (0.25 * s * ppm) as i32,
                Scalar::all(0.0),
                -1,
                imgproc::LINE_AA,
                0,
            )
            .unwrap();
        }
    }
    calibrate_warped("circles-asym:4x11:0.02", &canvas, ppm, margin, [0.07, 0.1]);
}
