use std::path::{Path, PathBuf};

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use slidetrack_core::{BoardLayout, CameraIntrinsics};

use super::*;
use crate::camera_info::read_camera_info;
use crate::marker_tool::{Refinement, ToolDictionary, detect_markers, detector_parameters, read_image};

fn testdata(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/testdata").join(rel)
}

/// OpenCV's tutorial GridBoard (`GridBoard::create(5, 7, 0.04, 0.01, dictionary)`,
/// opencv_contrib 4.6.0 `modules/aruco/tutorials/aruco_board_detection`).
fn tutorial_grid() -> BoardLayout {
    BoardLayout::Grid { markers_x: 5, markers_y: 7, marker_length_m: 0.04, separation_m: 0.01, first_id: 0 }
}

/// OpenCV's tutorial ChArUco board (`CharucoBoard::create(5, 7, 0.04f, 0.02f, dictionary)`,
/// `modules/aruco/samples/tutorial_charuco_create_detect.cpp`).
fn tutorial_charuco() -> BoardLayout {
    BoardLayout::Charuco { squares_x: 5, squares_y: 7, square_length_m: 0.04, marker_length_m: 0.02 }
}

fn camera(file: &str) -> CameraIntrinsics {
    let mut c = read_camera_info(testdata(&format!("aruco/{file}"))).unwrap().intrinsics;
    (c.width, c.height) = (640, 480);
    c
}

/// The markers of a photo with OpenCV's default detector, checked against
/// the corners OpenCV's own test asserts (`*.gt.json`, 1 px).
fn detect_checked(
    image: &str,
    dictionary: &str,
    gt: &str,
) -> (crate::marker_tool::Photo, Vec<MarkerDetection>) {
    let dictionary = ToolDictionary::load(testdata(dictionary).to_str().unwrap_or(dictionary))
        .or_else(|_| ToolDictionary::load(dictionary))
        .unwrap();
    let photo = read_image(&testdata(image)).unwrap();
    let found =
        detect_markers(&photo, &dictionary, &detector_parameters(None, Refinement::None).unwrap()).unwrap();
    let gt: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(testdata(gt)).unwrap()).unwrap();
    let markers = gt["markers"].as_array().unwrap();
    assert_eq!(found.len(), markers.len(), "{image}");
    for m in markers {
        let id = m["id"].as_u64().unwrap() as u32;
        let d = found.iter().find(|d| d.id == id).unwrap_or_else(|| panic!("{image}: marker {id} not found"));
        for (k, c) in m["corners"].as_array().unwrap().iter().enumerate() {
            for axis in 0..2 {
                let expected = c[axis].as_f64().unwrap();
                assert!((d.corners_px[k][axis] - expected).abs() <= 1.0, "{image} marker {id} corner {k}");
            }
        }
    }
    (photo, found)
}

#[test]
fn a_board_pose_is_recovered_exactly_from_its_projected_points() {
    let intrinsics = camera("tutorial_camera_charuco.yml");
    let truth = Isometry3::from_parts(
        Translation3::new(-0.08, -0.12, 0.55),
        UnitQuaternion::from_scaled_axis(Vector3::new(-0.4, 0.1, 0.2)),
    );
    for layout in [tutorial_grid(), tutorial_charuco()] {
        let object_m: Vec<_> = match layout {
            BoardLayout::Grid { .. } => layout.markers().iter().flat_map(|m| m.corners_m).collect(),
            BoardLayout::Charuco { .. } => layout.chessboard_corners_m(),
        };
        let image_px = object_m
            .iter()
            .map(|p| {
                let q = truth * p;
                let (u, v) = intrinsics.project([q.x, q.y, q.z]).unwrap();
                [u, v]
            })
            .collect();
        let obs = BoardObservation { ids: Vec::new(), object_m, image_px, markers: 0 };
        let pose = board_pose(&obs, &intrinsics).unwrap();
        let dt = (pose.camera_from_board.translation.vector - truth.translation.vector).norm();
        let dr = pose.camera_from_board.rotation.angle_to(&truth.rotation);
        assert!(dt < 1e-9 && dr < 1e-9, "{layout:?}: {dt} m, {dr} rad");
        assert!(pose.reprojection_error_px < 1e-6, "{}", pose.reprojection_error_px);
    }
}

#[test]
fn too_few_points_give_no_pose() {
    let obs = BoardObservation {
        ids: vec![0],
        object_m: vec![Point3::origin(); 3],
        image_px: vec![[1.0, 2.0]; 3],
        markers: 1,
    };
    let e = board_pose(&obs, &camera("tutorial_camera_params.yml")).unwrap_err();
    assert!(matches!(e, MarkerError::TooFewBoardPoints { points: 3, needed: 4 }), "{e}");
}

#[test]
fn the_gridboard_photo_gives_a_pose_from_all_35_markers() {
    let (photo, found) =
        detect_checked("aruco/gboriginal.png", "aruco/tutorial_dict.yml", "aruco/gboriginal.gt.json");
    let dictionary = ToolDictionary::load(testdata("aruco/tutorial_dict.yml").to_str().unwrap()).unwrap();
    let board = Board::with_dictionary(tutorial_grid(), &dictionary).unwrap();
    let intrinsics = camera("tutorial_camera_params.yml");
    let obs = board.observe_photo(&found, &photo, &intrinsics).unwrap();
    assert_eq!((obs.markers, obs.object_m.len()), (35, 140));
    let pose = board_pose(&obs, &intrinsics).unwrap();
    assert_eq!(pose.points, 140);
    // The corners are OpenCV's unrefined contour corners (integers): about 2 px.
    assert!(pose.reprojection_error_px < 3.0, "{}", pose.reprojection_error_px);
    // The board is in front of the camera, tilted away (its z into the board
    // points away from the camera).
    let t = pose.camera_from_board.translation.vector;
    assert!(t.z > 0.3 && t.z < 1.5, "{t}");
    assert!((pose.camera_from_board.rotation * Vector3::z()).z > 0.5);
}

#[test]
fn the_charuco_photo_gives_a_pose_from_its_interpolated_corners() {
    let (photo, found) = detect_checked("aruco/choriginal.jpg", "DICT_6X6_250", "aruco/choriginal.gt.json");
    let dictionary = ToolDictionary::load("DICT_6X6_250").unwrap();
    let board = Board::with_dictionary(tutorial_charuco(), &dictionary).unwrap();
    let intrinsics = camera("tutorial_camera_charuco.yml");
    let obs = board.observe_photo(&found, &photo, &intrinsics).unwrap();
    assert_eq!(obs.markers, 17);
    // Every inner corner of the 5x7 board is seen.
    assert_eq!(obs.object_m.len(), 24, "{:?}", obs.ids);
    let pose = board_pose(&obs, &intrinsics).unwrap();
    // Sub-pixel corners: a fraction of a pixel.
    assert!(pose.reprojection_error_px < 0.5, "{}", pose.reprojection_error_px);
    let t = pose.camera_from_board.translation.vector;
    assert!(t.z > 0.2 && t.z < 1.0, "{t}");
}
