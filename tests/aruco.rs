//! `slidetrack aruco detect` on OpenCV's tutorial photos: every marker found,
//! corners within the 1 px OpenCV's own tests assert.

mod common;

use std::path::PathBuf;

use common::{fails, ok, tempdir};
use serde_json::Value;

fn testdata(rel: &str) -> String {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/testdata").join(rel);
    path.to_str().expect("utf-8 path").to_string()
}

/// Runs `aruco detect` and checks every marker of the gold file is found with
/// its corners within the gold tolerance. Returns the output.
fn matches_gold(image: &str, gold: &str, extra: &[&str]) -> Value {
    let gold: Value = serde_json::from_str(&std::fs::read_to_string(testdata(gold)).expect("gold file"))
        .expect("gold JSON");
    let tolerance = gold["tolerance_px"].as_f64().expect("tolerance");
    let image = testdata(image);
    let mut args = vec!["aruco", "detect", image.as_str(), "--json"];
    args.extend_from_slice(extra);
    let out: Value = serde_json::from_str(&ok(&args)).expect("JSON output");
    let found = out["markers"].as_array().expect("markers");
    let expected = gold["markers"].as_array().expect("gold markers");
    assert_eq!(found.len(), expected.len(), "{image}: marker count");
    for g in expected {
        let id = g["id"].as_u64().expect("id");
        let m = found
            .iter()
            .find(|m| m["id"].as_u64() == Some(id))
            .unwrap_or_else(|| panic!("{image}: id {id} missing"));
        for (c, e) in m["corners_px"]
            .as_array()
            .expect("corners")
            .iter()
            .zip(g["corners"].as_array().expect("gold corners"))
        {
            for axis in 0..2 {
                let (got, want) = (c[axis].as_f64().expect("x"), e[axis].as_f64().expect("y"));
                assert!((got - want).abs() <= tolerance, "{image}: id {id} corner {c} vs {e}");
            }
        }
    }
    out
}

#[test]
fn every_marker_of_the_tutorial_photos_is_found_where_opencv_says() {
    matches_gold(
        "aruco/singlemarkersoriginal.jpg",
        "aruco/singlemarkersoriginal.gt.json",
        &["--dict", "DICT_6X6_250"],
    );
    matches_gold("aruco/choriginal.jpg", "aruco/choriginal.gt.json", &[]);
    let dict = testdata("aruco/tutorial_dict.yml");
    let out = matches_gold("aruco/gboriginal.png", "aruco/gboriginal.gt.json", &["--dict", &dict]);
    assert_eq!(out["dictionary"], dict.as_str());
}

#[test]
fn the_diamond_photo_gives_its_twelve_markers_with_opencvs_test_settings() {
    // OpenCV's diamond test: detector_params.yml with CORNER_REFINE_APRILTAG.
    let gold: Value = serde_json::from_str(
        &std::fs::read_to_string(testdata("aruco/diamondmarkers.gt.json")).expect("gold"),
    )
    .expect("gold JSON");
    let image = testdata("aruco/diamondmarkers.png");
    let dict = testdata("aruco/tutorial_dict.yml");
    let params = testdata("aruco/detector_params.yml");
    let out: Value = serde_json::from_str(&ok(&[
        "aruco", "detect", &image, "--dict", &dict, "--params", &params, "--refine", "apriltag", "--json",
    ]))
    .expect("JSON output");
    let markers = out["markers"].as_array().expect("markers");
    assert_eq!(markers.len() as u64, gold["n_markers"].as_u64().expect("n_markers"));
    for (id, count) in gold["marker_id_counts"].as_object().expect("id counts") {
        let found =
            markers.iter().filter(|m| m["id"].as_u64().map(|i| i.to_string()) == Some(id.clone())).count();
        assert_eq!(found as u64, count.as_u64().expect("count"), "id {id}");
    }
}

#[test]
fn with_intrinsics_and_a_size_the_poses_are_printed() {
    let camera = testdata("aruco/tutorial_camera_params.yml");
    let image = testdata("aruco/singlemarkersoriginal.jpg");
    let out: Value = serde_json::from_str(&ok(&[
        "aruco",
        "detect",
        &image,
        "--camera",
        &camera,
        "--marker-size",
        "0.05",
        "--json",
    ]))
    .unwrap();
    for m in out["markers"].as_array().unwrap() {
        let z = m["pose"]["position_in_camera_m"][2].as_f64().unwrap();
        assert!(z > 0.1 && z < 2.0, "marker {} at depth {z} m", m["id"]);
        assert!(m["pose"]["reprojection_error_px"].as_f64().unwrap() < 2.0);
    }
    let text = ok(&["aruco", "detect", &image]);
    assert!(text.contains("6 marker(s) of DICT_6X6_250"), "{text}");
}

#[test]
fn bad_input_gives_one_clear_error() {
    let image = testdata("aruco/singlemarkersoriginal.jpg");
    let e = fails(&["aruco", "detect", "/nonexistent/photo.png"]);
    assert!(e.contains("/nonexistent/photo.png"), "{e}");
    let e = fails(&["aruco", "detect", &image, "--dict", "DICT_9X9_1"]);
    assert!(e.contains("DICT_9X9_1") && e.contains("DICT_6X6_250"), "{e}");
    let dir = tempdir();
    let yaml = dir.path().join("camera.yaml");
    std::fs::write(
        &yaml,
        "image_width: 640\nimage_height: 480\ncamera_name: c\ndistortion_model: plumb_bob\n",
    )
    .unwrap();
    let e = fails(&["aruco", "detect", &image, "--camera", yaml.to_str().unwrap(), "--marker-size", "0.05"]);
    assert!(e.contains("camera_matrix") && e.contains("camera.yaml"), "{e}");
}

#[test]
fn with_intrinsics_and_a_board_the_boards_pose_is_printed() {
    let dir = tempdir();
    let board = dir.path().join("board.toml");
    // OpenCV's tutorial ChArUco board (samples/tutorial_charuco_create_detect.cpp).
    std::fs::write(
        &board,
        "kind = \"charuco\"\nsquares_x = 5\nsquares_y = 7\nsquare_length_m = 0.04\nmarker_length_m = 0.02\n",
    )
    .unwrap();
    let (image, camera) = (testdata("aruco/choriginal.jpg"), testdata("aruco/tutorial_camera_charuco.yml"));
    let board = board.to_str().unwrap();
    let out: Value = serde_json::from_str(&ok(&[
        "aruco", "detect", &image, "--camera", &camera, "--board", board, "--json",
    ]))
    .unwrap();
    let b = &out["board"];
    assert_eq!((b["markers"].as_u64(), b["pose"]["points"].as_u64()), (Some(17), Some(24)), "{b}");
    assert!(b["pose"]["reprojection_error_px"].as_f64().unwrap() < 0.5, "{b}");
    let text = ok(&["aruco", "detect", &image, "--camera", &camera, "--board", board]);
    assert!(text.contains("board: 17 marker(s), 24 point(s)"), "{text}");
    // A board without a camera is refused by the argument parser; a bad layout names its field.
    let out = common::run(&["aruco", "detect", &image, "--board", board]);
    assert!(!out.status.success() && String::from_utf8_lossy(&out.stderr).contains("--camera"));
    std::fs::write(dir.path().join("bad.toml"), "kind = \"grid\"\nmarkers_x = 5\n").unwrap();
    let bad = dir.path().join("bad.toml");
    let e = fails(&["aruco", "detect", &image, "--camera", &camera, "--board", bad.to_str().unwrap()]);
    assert!(e.contains("bad.toml") && e.contains("markers_y"), "{e}");
}
