//! The `[rgbd]` table: what parses, and the field each bad value is blamed on.

use super::*;

#[derive(Deserialize)]
struct Rig {
    rgbd: RgbdCameraConfig,
}

fn parse(text: &str) -> Result<RgbdCameraConfig, String> {
    let rig: Rig = slidetrack_core::parse_toml(text, "rig.toml").map_err(|e| e.to_string())?;
    rig.rgbd.validate().map_err(|e| e.to_string())?;
    Ok(rig.rgbd)
}

const INTRINSICS: &str = "{ width = 640, height = 480, fx = 600.0, fy = 600.0, cx = 320.0, cy = 240.0, distortion = [0.0, 0.0, 0.0, 0.0, 0.0] }";

fn v4l2(extra: &str) -> String {
    format!(
        "[rgbd]\nkind = \"v4l2\"\n{extra}\n[rgbd.color]\ndevice = \"/dev/video4\"\nintrinsics = {INTRINSICS}\n\
         [rgbd.depth]\ndevice = \"/dev/video0\"\npixel_format = \"z16\"\nintrinsics = {INTRINSICS}\n"
    )
}

#[test]
fn a_v4l2_camera_parses_with_the_realsense_defaults() {
    let RgbdCameraConfig::V4l2(c) = parse(&v4l2("")).unwrap() else { panic!("not v4l2") };
    assert_eq!(c.depth.pixel_format, V4l2PixelFormat::Z16, "lower case accepted");
    // A node's table starts from `[hw.camera]`'s defaults (MJPG); depth must say Z16.
    assert_eq!(c.color.pixel_format, V4l2PixelFormat::Mjpg);
    assert_eq!(c.depth_scale_m, 0.001);
    assert_eq!(c.color.startup_timeout_ms, 5000);
    assert!(c.depth_to_color.is_none());
}

#[test]
fn the_module_example_parses() {
    let doc = include_str!("../rgbd_config.rs");
    let example: String = doc
        .lines()
        .skip_while(|l| !l.starts_with("//! ```toml"))
        .skip(1)
        .take_while(|l| !l.starts_with("//! ```"))
        .map(|l| format!("{}\n", l.trim_start_matches("//!").trim_start()))
        .collect();
    let RgbdCameraConfig::V4l2(c) = parse(&example).unwrap() else { panic!("not v4l2") };
    let e = c.depth_to_color.unwrap().inline("rgbd.depth_to_color").unwrap();
    assert_eq!(e.translation_m, [0.015, 0.0, 0.0]);
}

#[test]
fn bad_values_name_their_field() {
    let cases = [
        (v4l2("depth_scale_m = 0.0"), "rgbd.depth_scale_m"),
        (v4l2("pairing_tolerance_ms = -1.0"), "rgbd.pairing_tolerance_ms"),
        (v4l2("").replace("pixel_format = \"z16\"", "pixel_format = \"YUYV\""), "rgbd.depth.pixel_format"),
        (
            v4l2("").replace("device = \"/dev/video4\"", "device = \"/dev/video4\"\npixel_format = \"Z16\""),
            "rgbd.color.pixel_format",
        ),
        (v4l2("").replacen(&format!("intrinsics = {INTRINSICS}\n"), "", 1), "rgbd.color"),
        (v4l2("").replace("device = \"/dev/video0\"", "device = \"/dev/video0\"\nwidth = 848"), "rgbd.depth"),
        (
            v4l2("").replace("device = \"/dev/video0\"", "device = \"/dev/video0\"\nstartup_timeout_ms = 0"),
            "rgbd.depth.startup_timeout_ms",
        ),
        (
            v4l2("depth_to_color = { rotation_row_major = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0] }"),
            "rgbd.depth_to_color: needs translation_m",
        ),
        (
            v4l2(
                "depth_to_color = { rotation_row_major = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, -1.0], translation_m = [0.0, 0.0, 0.0] }",
            ),
            "rgbd.depth_to_color: the rotation is not a rotation matrix (determinant",
        ),
        (
            v4l2(
                "depth_to_color = { rotation_row_major = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0], translation_m = [15.0, 0.0, 0.0] }",
            ),
            "rgbd.depth_to_color: translation_m",
        ),
        ("[rgbd]\nkind = \"recording\"\n".to_string(), "exactly one of `session` and `directory`"),
        ("[rgbd]\nkind = \"recording\"\ndirectory = \"frames\"\n".to_string(), "rgbd.color_intrinsics"),
        ("[rgbd]\nkind = \"recording\"\nsession = \"s.mcap\"\nfps = 0.0\n".to_string(), "rgbd.fps"),
        (
            "[rgbd]\nkind = \"recording\"\nsession = \"s.mcap\"\nframes = 3\n".to_string(),
            "unknown field `frames`",
        ),
        ("[rgbd]\nkind = \"realsense\"\n".to_string(), "unknown variant `realsense`"),
    ];
    for (text, field) in cases {
        let e = parse(&text).expect_err(field);
        assert!(e.contains(field), "{field}: {e}");
    }
}

#[test]
fn librealsense_column_major_rotations_are_transposed() {
    // A 90 degree turn about z: x -> y.
    let row_major = [0.0, -1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0];
    let column_major = [0.0, 1.0, 0.0, -1.0, 0.0, 0.0, 0.0, 0.0, 1.0];
    let d = DepthToColor {
        rotation_column_major: Some(column_major),
        translation_m: Some([0.01, 0.0, 0.0]),
        ..DepthToColor::default()
    };
    assert_eq!(d.inline("x").unwrap().rotation_row_major, row_major);
    let both = DepthToColor { rotation_row_major: Some(row_major), ..d };
    assert!(both.inline("x").unwrap_err().to_string().contains("not both"));
}
