//! Both formats round-trip; OpenCV's own files read; bad files say what is wrong.

use super::*;

fn info() -> CameraInfo {
    CameraInfo {
        camera_name: "sim camera".into(),
        intrinsics: CameraIntrinsics {
            width: 640,
            height: 480,
            fx: 600.25,
            fy: 601.5,
            cx: 321.5,
            cy: 238.0,
            distortion: [-0.1, 0.02, 0.0004, -0.0003, 0.001],
        },
        avg_reprojection_error_px: Some(0.25),
    }
}

fn testdata(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/testdata").join(rel)
}

#[test]
fn ros_yaml_round_trips_and_has_every_field() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("camera.yaml");
    write_camera_info(&path, &info(), CalibrationFormat::Ros).unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    for field in ROS_FIELDS {
        assert!(text.contains(&format!("{field}:")), "{field} missing from\n{text}");
    }
    let back = read_camera_info(&path).unwrap();
    assert_eq!(back, CameraInfo { avg_reprojection_error_px: None, ..info() });
}

#[test]
fn opencv_yaml_round_trips() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("camera.yml");
    write_camera_info(&path, &info(), CalibrationFormat::OpenCv).unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    assert!(text.starts_with("%YAML:1.0"), "{text}");
    for field in
        ["camera_matrix", "distortion_coefficients", "image_width", "image_height", "avg_reprojection_error"]
    {
        assert!(text.contains(&format!("{field}:")), "{field} missing from\n{text}");
    }
    assert_eq!(read_camera_info(&path).unwrap(), info());
}

#[test]
fn opencvs_own_files_are_read() {
    let left = read_camera_info(testdata("calib/opencv_left/left_intrinsics.yml")).unwrap();
    let c = &left.intrinsics;
    assert_eq!((c.width, c.height), (640, 480));
    assert!((c.fx - 535.915733961632).abs() < 1e-9 && (c.cy - 235.57082909788173).abs() < 1e-9);
    assert!((c.distortion[4] - 0.23839153080878486).abs() < 1e-12);
    assert!((left.avg_reprojection_error_px.unwrap() - 0.39259098975581364).abs() < 1e-12);
    // The ArUco tutorial's file has no image size.
    let tutorial = read_camera_info(testdata("aruco/tutorial_camera_params.yml")).unwrap();
    assert!(!tutorial.has_image_size());
    assert_eq!(tutorial.intrinsics.fx, 628.158);
}

#[test]
fn a_missing_field_is_named() {
    let full = to_ros_yaml(&info());
    for field in ROS_FIELDS {
        let text: String = full
            .split_inclusive('\n')
            .scan(false, |skipping, line| {
                let starts = line.starts_with(&format!("{field}:"));
                *skipping = starts || (*skipping && line.starts_with(' '));
                Some(if *skipping { String::new() } else { line.to_string() })
            })
            .collect();
        let err = parse_camera_info(&text, Path::new("cam.yaml")).unwrap_err();
        let msg = err.to_string();
        assert!(matches!(err, CameraInfoError::MissingField { .. }), "{field}: {msg}");
        assert!(msg.contains(&format!("`{field}`")) && msg.contains("cam.yaml"), "{msg}");
    }
    let opencv = "%YAML:1.0\n---\nimage_width: 640\n";
    let msg = parse_camera_info(opencv, Path::new("cv.yml")).unwrap_err().to_string();
    assert!(msg.contains("`camera_matrix`"), "{msg}");
}

#[test]
fn bad_values_and_bad_yaml_are_reported() {
    let text =
        to_ros_yaml(&info()).replace("rows: 1\n  cols: 5\n  data: [", "rows: 1\n  cols: 5\n  data: [oops, ");
    let msg = parse_camera_info(&text, Path::new("c.yaml")).unwrap_err().to_string();
    assert!(msg.contains("distortion_coefficients"), "{msg}");
    let text = to_ros_yaml(&info()).replace("image_width: 640", "image_width: -3");
    let msg = parse_camera_info(&text, Path::new("c.yaml")).unwrap_err().to_string();
    assert!(msg.contains("image_width"), "{msg}");
    let text = to_ros_yaml(&info()).replace("plumb_bob", "equidistant");
    assert!(matches!(
        parse_camera_info(&text, Path::new("c.yaml")),
        Err(CameraInfoError::UnsupportedDistortion { .. })
    ));
    let msg = parse_camera_info("camera_matrix: [1, 2\n", Path::new("c.yaml")).unwrap_err().to_string();
    assert!(msg.contains("not valid YAML"), "{msg}");
    let err = read_camera_info("/nonexistent/camera.yaml").unwrap_err();
    assert!(err.to_string().contains("/nonexistent/camera.yaml"));
}
