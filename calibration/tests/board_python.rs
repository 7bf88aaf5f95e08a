//! Board poses on OpenCV's real photos against an independent OpenCV
//! computation through its Python bindings (`tests/python/board_pose_reference.py`,
//! `opencv-python-headless` in the project's Python environment).
//!
//! For the same points (the corners slidetrack detected and matched) the
//! two poses must agree within 0.5 mm and 0.1 degree. The Python side
//! matches the points to its own board objects (`cv2.aruco.GridBoard`,
//! `cv2.aruco.CharucoBoard`), so a wrong layout here shows. Its own
//! detection (OpenCV 4.13's detector and ChArUco interpolation) must give
//! the same pose within the same bounds.
//!
//! Skipped, with a message, when the project's Python (`SLIDETRACK_PYTHON`,
//! else `target/pyenv`, made by `scripts/setup.sh --test`) or its `cv2` is absent.

use std::path::{Path, PathBuf};
use std::process::Command;

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use slidetrack_calibration::camera_info::read_camera_info;
use slidetrack_calibration::marker_tool::{
    Refinement, ToolDictionary, detect_markers, detector_parameters, read_image,
};
use slidetrack_calibration::{Board, BoardObservation, BoardPose, board_pose};
use slidetrack_core::BoardLayout;

fn testdata(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/testdata").join(rel)
}

fn python() -> Option<PathBuf> {
    let python = std::env::var_os("SLIDETRACK_PYTHON").map_or_else(
        || Path::new(env!("CARGO_MANIFEST_DIR")).join("../target/pyenv/bin/python"),
        PathBuf::from,
    );
    let has_cv2 = Command::new(&python).args(["-c", "import cv2"]).output().is_ok_and(|o| o.status.success());
    if !has_cv2 {
        eprintln!(
            "skipped: {} with cv2 not found (run `scripts/setup.sh --test`, or set SLIDETRACK_PYTHON)",
            python.display()
        );
        return None;
    }
    Some(python)
}

struct Case {
    image: &'static str,
    dictionary: String,
    camera: &'static str,
    layout: BoardLayout,
}

/// slidetrack's observation and pose of a photo's board.
fn slidetrack_pose(case: &Case) -> (BoardObservation, BoardPose) {
    let dictionary = ToolDictionary::load(&case.dictionary).expect("dictionary");
    let photo = read_image(&testdata(case.image)).expect("photo");
    let found =
        detect_markers(&photo, &dictionary, &detector_parameters(None, Refinement::None).expect("defaults"))
            .expect("detection");
    let mut intrinsics = read_camera_info(testdata(case.camera)).expect("camera file").intrinsics;
    (intrinsics.width, intrinsics.height) = (photo.width, photo.height);
    let board = Board::with_dictionary(case.layout.clone(), &dictionary).expect("board");
    let obs = board.observe_photo(&found, &photo, &intrinsics).expect("board points");
    let pose = board_pose(&obs, &intrinsics).expect("board pose");
    (obs, pose)
}

fn isometry(pose: &serde_json::Value) -> Isometry3<f64> {
    let v = |key: &str| {
        let a: Vec<f64> =
            pose[key].as_array().expect("a vector").iter().map(|x| x.as_f64().expect("a number")).collect();
        Vector3::new(a[0], a[1], a[2])
    };
    Isometry3::from_parts(Translation3::from(v("tvec_m")), UnitQuaternion::from_scaled_axis(v("rvec")))
}

/// (translation difference in mm, rotation difference in degrees).
fn difference(a: &Isometry3<f64>, b: &Isometry3<f64>) -> (f64, f64) {
    (
        (a.translation.vector - b.translation.vector).norm() * 1e3,
        a.rotation.angle_to(&b.rotation).to_degrees(),
    )
}

fn check(case: &Case, python: &Path) {
    let (obs, pose) = slidetrack_pose(case);
    let dir = tempfile::tempdir().expect("temporary directory");
    let request = dir.path().join("request.json");
    let body = serde_json::json!({
        "image": testdata(case.image),
        "dictionary": case.dictionary,
        "camera": testdata(case.camera),
        // slidetrack's TOML form of the layout, as JSON.
        "board": serde_json::to_value(&case.layout).expect("layout as JSON"),
        "given": {"ids": obs.ids, "image_px": obs.image_px},
    });
    std::fs::write(&request, body.to_string()).expect("request written");
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/python/board_pose_reference.py");
    let out = Command::new(python).arg(&script).arg(&request).output().expect("python runs");
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let reference: serde_json::Value = serde_json::from_slice(&out.stdout).expect("JSON from the script");
    let given = &reference["given"];
    assert_eq!(given["points"].as_u64().expect("a count") as usize, pose.points);
    let (dt_mm, dr_deg) = difference(&pose.camera_from_board, &isometry(given));
    let own = &reference["own"]["pose"];
    let (own_dt_mm, own_dr_deg) = difference(&pose.camera_from_board, &isometry(own));
    eprintln!(
        "{}: {} points, RMS {:.3} px (Python {:.3} px); same points: {dt_mm:.2e} mm, {dr_deg:.2e} deg; \
         Python's own detection ({} points, OpenCV {}): {own_dt_mm:.2e} mm, {own_dr_deg:.2e} deg",
        case.image,
        pose.points,
        pose.reprojection_error_px,
        given["rms_px"].as_f64().expect("a number"),
        own["points"],
        reference["opencv"],
    );
    assert!(dt_mm < 0.5 && dr_deg < 0.1, "{}: {dt_mm} mm, {dr_deg} deg", case.image);
    assert!((pose.reprojection_error_px - given["rms_px"].as_f64().expect("a number")).abs() < 1e-3);
    // Python's own detection: the same markers and points.
    let markers = reference["own"]["markers"].as_object().expect("markers by id");
    assert_eq!(markers.len(), pose.markers, "{}", case.image);
    assert_eq!(own["points"].as_u64().expect("a count") as usize, pose.points, "{}", case.image);
    // Another OpenCV version's own detection finds the same corners here.
    assert!(own_dt_mm < 0.5 && own_dr_deg < 0.1, "{}: {own_dt_mm} mm, {own_dr_deg} deg", case.image);
}

#[test]
fn board_poses_agree_with_opencv_python_on_opencvs_photos() {
    let Some(python) = python() else { return };
    let grid = Case {
        image: "aruco/gboriginal.png",
        dictionary: testdata("aruco/tutorial_dict.yml").to_str().unwrap().to_string(),
        camera: "aruco/tutorial_camera_params.yml",
        layout: BoardLayout::Grid {
            markers_x: 5,
            markers_y: 7,
            marker_length_m: 0.04,
            separation_m: 0.01,
            first_id: 0,
        },
    };
    check(&grid, &python);
    let charuco = Case {
        image: "aruco/choriginal.jpg",
        dictionary: "DICT_6X6_250".into(),
        camera: "aruco/tutorial_camera_charuco.yml",
        layout: BoardLayout::Charuco {
            squares_x: 5,
            squares_y: 7,
            square_length_m: 0.04,
            marker_length_m: 0.02,
        },
    };
    check(&charuco, &python);
}
