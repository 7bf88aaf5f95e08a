//! `slidetrack calibrate camera` on OpenCV's chessboard photos and on the
//! simulated camera, and its refusals.

mod common;

use std::path::PathBuf;

use common::{fails, ok, run, tempdir};
use serde_json::Value;

fn testdata(rel: &str) -> String {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/testdata").join(rel);
    path.to_str().expect("utf-8 path").to_string()
}

#[test]
fn opencvs_13_chessboard_views_give_opencvs_calibration_in_both_formats() {
    let dir = tempdir();
    let ros = dir.path().join("left.yaml");
    let images = format!("{}/left*.jpg", testdata("calib/opencv_left"));
    let out: Value = serde_json::from_str(&ok(&[
        "-q",
        "calibrate",
        "camera",
        "--images",
        &images,
        "--pattern",
        "chessboard:9x6:0.025",
        "--out",
        ros.to_str().unwrap(),
        "--json",
    ]))
    .unwrap();
    // cv2.calibrateCamera on the same views (flags 0): RMS 0.4088 px, fx 536.07, fy 536.02, cx 342.37, cy 235.54.
    assert_eq!(out["views"], 13);
    let rms = out["rms_px"].as_f64().unwrap();
    assert!((rms - 0.4088).abs() < 0.001, "RMS {rms}");
    let (fx, fy) = (out["fx"].as_f64().unwrap(), out["fy"].as_f64().unwrap());
    assert!((fx - 536.07).abs() / 536.07 < 0.005 && (fy - 536.02).abs() / 536.02 < 0.005, "{out}");
    assert!(
        (out["cx"].as_f64().unwrap() - 342.37).abs() < 2.0
            && (out["cy"].as_f64().unwrap() - 235.54).abs() < 2.0
    );
    let text = std::fs::read_to_string(&ros).unwrap();
    for field in [
        "image_width",
        "image_height",
        "camera_name",
        "camera_matrix",
        "distortion_model",
        "distortion_coefficients",
        "rectification_matrix",
        "projection_matrix",
    ] {
        assert!(text.contains(&format!("{field}:")), "{field} missing:\n{text}");
    }

    // OpenCV format, read back by slidetrack (aruco detect uses it for poses).
    let cv = dir.path().join("left.yml");
    let fixed = ok(&[
        "-q",
        "calibrate",
        "camera",
        "--images",
        &images,
        "--pattern",
        "chessboard:9x6:0.025",
        "--out",
        cv.to_str().unwrap(),
        "--format",
        "opencv",
        "--fix-aspect-ratio",
    ]);
    assert!(fixed.contains("RMS reprojection error 0.409"), "{fixed}");
    let text = std::fs::read_to_string(&cv).unwrap();
    assert!(text.starts_with("%YAML:1.0") && text.contains("avg_reprojection_error"), "{text}");
    let photo = testdata("calib/opencv_left/left01.jpg");
    ok(&["aruco", "detect", &photo, "--camera", cv.to_str().unwrap(), "--marker-size", "0.02"]);
}

#[test]
fn the_simulated_camera_is_calibrated_live_to_its_true_intrinsics() {
    let dir = tempdir();
    let out_file = dir.path().join("sim.yaml");
    let out: Value = serde_json::from_str(&ok(&[
        "-q",
        "calibrate",
        "camera",
        "--sim",
        "--views",
        "12",
        "--pattern",
        "chessboard:9x6:0.025",
        "--out",
        out_file.to_str().unwrap(),
        "--json",
    ]))
    .unwrap();
    // The simulated camera: fx = fy = 600, cx = 321.5, cy = 238.
    let (fx, fy) = (out["fx"].as_f64().unwrap(), out["fy"].as_f64().unwrap());
    assert!((fx - 600.0).abs() / 600.0 < 0.005 && (fy - 600.0).abs() / 600.0 < 0.005, "{out}");
    assert!(
        (out["cx"].as_f64().unwrap() - 321.5).abs() < 2.0
            && (out["cy"].as_f64().unwrap() - 238.0).abs() < 2.0,
        "{out}"
    );
    assert_eq!(out["views"], 12);
}

#[test]
fn board_views_rendered_by_the_simulated_rig_are_saved_and_calibrate_from_the_files() {
    let dir = tempdir();
    let views = dir.path().join("views");
    let live = dir.path().join("live.yaml");
    ok(&[
        "-q",
        "calibrate",
        "camera",
        "--sim",
        "--views",
        "12",
        "--pattern",
        "chessboard:9x6:0.025",
        "--save-views",
        views.to_str().unwrap(),
        "--out",
        live.to_str().unwrap(),
    ]);
    let mut saved: Vec<_> = std::fs::read_dir(&views).unwrap().map(|e| e.unwrap().file_name()).collect();
    saved.sort();
    assert_eq!(saved.len(), 12, "{saved:?}");
    assert_eq!(saved[0], "view-00.png");

    let files = dir.path().join("files.yml");
    let glob = format!("{}/view-*.png", views.display());
    let out: Value = serde_json::from_str(&ok(&[
        "-q",
        "calibrate",
        "camera",
        "--images",
        &glob,
        "--pattern",
        "chessboard:9x6:0.025",
        "--format",
        "opencv",
        "--out",
        files.to_str().unwrap(),
        "--json",
    ]))
    .unwrap();
    // The simulated camera: fx = fy = 600, cx = 321.5, cy = 238.
    let (fx, fy) = (out["fx"].as_f64().unwrap(), out["fy"].as_f64().unwrap());
    assert!((fx - 600.0).abs() / 600.0 < 0.005 && (fy - 600.0).abs() / 600.0 < 0.005, "{out}");
    let (cx, cy) = (out["cx"].as_f64().unwrap(), out["cy"].as_f64().unwrap());
    assert!((cx - 321.5).abs() < 2.0 && (cy - 238.0).abs() < 2.0, "{out}");
    assert_eq!(out["views"], 12);
    // Lossless views: the same result as the live calibration, written in the other format.
    let text = std::fs::read_to_string(&files).unwrap();
    assert!(text.starts_with("%YAML:1.0"), "{text}");
}

/// A V4L2 capture device to test on: `SLIDETRACK_V4L2`, else the first `/dev/video*`.
fn v4l2_device() -> Option<String> {
    if let Ok(named) = std::env::var("SLIDETRACK_V4L2") {
        return Some(named);
    }
    let mut nodes: Vec<String> = std::fs::read_dir("/dev")
        .ok()?
        .filter_map(|e| e.ok())
        .map(|e| e.path().display().to_string())
        .filter(|p| p.starts_with("/dev/video"))
        .collect();
    nodes.sort();
    nodes.into_iter().next()
}

#[test]
fn live_calibration_from_a_v4l2_camera_ends_cleanly() {
    let Some(device) = v4l2_device() else {
        eprintln!(
            "skipping the live V4L2 calibration test: no /dev/video* node (plug in a camera, or name one in \
             SLIDETRACK_V4L2)"
        );
        return;
    };
    // Nobody moves a board in front of the camera during the test: either a
    // calibration (a board is there) or one clear line saying how many views
    // were captured.
    let dir = tempdir();
    let out_file = dir.path().join("v4l2.yaml");
    let out = run(&[
        "calibrate",
        "camera",
        "--device",
        &device,
        "--views",
        "3",
        "--timeout",
        "5",
        "--pattern",
        "chessboard:9x6:0.025",
        "--out",
        out_file.to_str().unwrap(),
    ]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!stderr.contains("panicked"), "{stderr}");
    if out.status.success() {
        assert!(out_file.exists());
    } else {
        assert_eq!(out.status.code(), Some(1), "{stderr}");
        let last = stderr.lines().last().unwrap_or_default();
        assert!(last.contains(&device) || last.contains("views"), "{stderr}");
    }
}

#[test]
fn images_without_the_pattern_and_bad_patterns_are_refused() {
    let dir = tempdir();
    let out_file = dir.path().join("c.yaml");
    let photo = testdata("aruco/singlemarkersoriginal.jpg");
    let e = fails(&[
        "-q",
        "calibrate",
        "camera",
        "--images",
        &photo,
        "--pattern",
        "chessboard:9x6:0.025",
        "--out",
        out_file.to_str().unwrap(),
    ]);
    assert!(e.contains("found in 0 of 1") && e.contains("singlemarkersoriginal.jpg"), "{e}");
    assert!(!out_file.exists(), "nothing written");
    let e = fails(&["calibrate", "camera", "--images", &photo, "--pattern", "chessboard:9x6"]);
    assert!(e.contains("chessboard:9x6"), "{e}");
    let e = fails(&[
        "calibrate",
        "camera",
        "--images",
        "/nonexistent/*.jpg",
        "--pattern",
        "chessboard:9x6:0.025",
    ]);
    assert!(e.contains("/nonexistent/*.jpg"), "{e}");
    let e = fails(&["calibrate", "camera", "--sim", "--pattern", "circles-asym:4x11:0.02"]);
    assert!(e.contains("chessboards only"), "{e}");
    let out = run(&[
        "calibrate",
        "camera",
        "--device",
        "/dev/video-none",
        "--pattern",
        "chessboard:9x6:0.025",
        "--timeout",
        "1",
    ]);
    assert_eq!(out.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("/dev/video-none") && !stderr.contains("panicked"), "{stderr}");
}
