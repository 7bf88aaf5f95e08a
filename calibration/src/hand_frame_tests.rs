use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};

use super::*;

/// What `calibrate hand --out` writes (a comment line, then `[camera]`).
const WRITTEN: &str = "# calibrate hand (simulated camera): 20 frames; standard error 0.1 mm, 0.01 deg\n[camera]\n\
    placement = { kind = \"pose\", translation_m = [0.300000, 0.010000, 0.100000], quaternion_xyzw = [0.0, 0.0, 0.70710678, 0.70710678] }\n";

fn close(a: &Vector3<f64>, b: [f64; 3]) -> bool {
    (a - Vector3::from(b)).norm() < 1e-12
}

#[test]
fn the_default_gripper_slides_down_between_pads_closing_along_y() {
    let a = HandGeometry::default().axes("test").unwrap();
    assert!(close(&a.sliding, [0.0, 0.0, -1.0]), "{:?}", a.sliding);
    let c = HandGeometry::default().contact_frame("test").unwrap();
    assert!(close(&c.n(), [0.0, 1.0, 0.0]) && close(&c.x(), [0.0, 0.0, -1.0]), "{c:?}");
    assert!(close(&c.y(), [-1.0, 0.0, 0.0]), "y = n x x points into the palm: {c:?}");
    assert_eq!(c.origin_m, [0.10, 0.0, 0.0]);
}

#[test]
fn a_tilted_finger_axis_is_made_perpendicular_to_the_closing_axis() {
    // Fingers 30 deg below the palm's normal, pads closing along y: the
    // sliding axis is perpendicular to both, in the pads' plane.
    let g =
        HandGeometry { finger_axis_in_hand: [0.866_025_403_784_438_6, 0.2, -0.5], ..HandGeometry::default() };
    let a = g.axes("test").unwrap();
    assert!(close(&a.fingers, [0.866_025_403_784_438_6, 0.0, -0.5]), "{:?}", a.fingers);
    assert!(close(&a.sliding, [-0.5, 0.0, -0.866_025_403_784_438_6]), "{:?}", a.sliding);
    assert!(a.sliding.dot(&a.closing).abs() < 1e-12 && a.sliding.dot(&a.fingers).abs() < 1e-12);
}

#[test]
fn parallel_or_zero_axes_are_refused_naming_the_source() {
    let parallel = HandGeometry { finger_axis_in_hand: [0.0, 1.0, 0.1], ..HandGeometry::default() };
    let e = parallel.axes("rig.toml").unwrap_err().to_string();
    assert!(e.contains("rig.toml") && e.contains("deg apart"), "{e}");
    let zero = HandGeometry { closing_axis_in_hand: [0.0; 3], ..HandGeometry::default() };
    assert!(zero.axes("x").unwrap_err().to_string().contains("closing_axis_in_hand"));
}

#[test]
fn the_file_calibrate_hand_writes_is_a_hand_calibration() {
    let file = HandCalibrationFile::parse(WRITTEN, Path::new("hand.toml")).unwrap();
    let expected = Isometry3::from_parts(
        Translation3::new(0.3, 0.01, 0.1),
        UnitQuaternion::from_axis_angle(&Vector3::z_axis(), std::f64::consts::FRAC_PI_2),
    );
    assert!((file.hand_from_camera.to_homogeneous() - expected.to_homogeneous()).norm() < 1e-7);
    assert_eq!(file.geometry, None);
    // A camera point 0.2 m in front of the lens, in the hand frame.
    let frame = file.hand_frame(None).unwrap();
    let p = frame.in_hand(&Point3::new(0.0, 0.0, 0.2));
    assert!((p - Point3::new(0.3, 0.01, 0.3)).norm() < 1e-7, "{p}");
    assert_eq!(frame.geometry_from, "the default [hand_geometry]");
    assert!(frame.axis_source().contains("hand.toml"));
}

#[test]
fn the_geometry_comes_from_the_file_else_the_sessions_rig_config_else_the_defaults() {
    let rig = "[sim]\nhand = \"gripper\"\n[hand_geometry]\nclosing_axis_in_hand = [0.0, 0.0, 1.0]\n";
    let file = HandCalibrationFile::parse(WRITTEN, Path::new("hand.toml")).unwrap();
    let frame = file.hand_frame(Some(rig)).unwrap();
    assert!(frame.geometry_from.contains("rig_config"), "{}", frame.geometry_from);
    // Closing along z, fingers along x: it slides along z x x = +y.
    assert!(close(&frame.axes.sliding, [0.0, 1.0, 0.0]), "{:?}", frame.axes.sliding);
    let own = format!("{WRITTEN}[hand_geometry]\nfinger_axis_in_hand = [0.0, 0.0, -1.0]\n");
    let file = HandCalibrationFile::parse(&own, Path::new("hand.toml")).unwrap();
    let frame = file.hand_frame(Some(rig)).unwrap();
    assert!(frame.geometry_from.contains("hand.toml"), "{}", frame.geometry_from);
    // Closing along y, fingers down: it slides along y x -z = -x.
    assert!(close(&frame.axes.sliding, [-1.0, 0.0, 0.0]), "{:?}", frame.axes.sliding);
}

#[test]
fn a_file_without_a_placement_or_with_a_bad_geometry_is_refused_naming_it() {
    let e = HandCalibrationFile::parse("[sim]\n", Path::new("cal.toml")).unwrap_err().to_string();
    assert!(e.contains("cal.toml") && e.contains("[camera] placement"), "{e}");
    let bad = format!("{WRITTEN}[hand_geometry]\nfinger_axis_in_hand = [0.0, 2.0, 0.0]\n");
    let e = HandCalibrationFile::parse(&bad, Path::new("cal.toml")).unwrap_err().to_string();
    assert!(e.contains("cal.toml") && e.contains("deg apart"), "{e}");
    let typo = format!("{WRITTEN}[hand_geometry]\nfinger_axis = [0.0, 0.0, 1.0]\n");
    let e = HandCalibrationFile::parse(&typo, Path::new("cal.toml")).unwrap_err().to_string();
    assert!(e.contains("cal.toml") && e.contains("finger_axis"), "{e}");
    let e = HandCalibrationFile::load(Path::new("/nonexistent/cal.toml")).unwrap_err().to_string();
    assert!(e.contains("/nonexistent/cal.toml"), "{e}");
}
