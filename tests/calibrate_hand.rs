//! `slidetrack calibrate hand` on the simulated rig with a known, non-default
//! camera placement: the judged recovery (2 mm, 0.5 degree), the output file
//! read back as a rig config, and the refusal without a hand target; the same
//! from a recorded session (`--session`) of the simulated camera's frames,
//! and its refusals (no colour frames, target never seen).

mod common;

use std::path::{Path, PathBuf};

use common::{fails, ok, tempdir};
use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion, Vector3};
use serde_json::Value;
use slidetrack_experiment::hand_calibration_session::{HandTargetRecording, record_hand_target_session};

// The camera off the default placement, and the hand's target.
use common::HAND_TARGET_RIG as RIG;

#[test]
fn calibrate_hand_on_the_simulated_rig_recovers_the_placement_within_2_mm_and_half_a_degree() {
    let dir = tempdir();
    let rig = dir.path().join("rig.toml");
    std::fs::write(&rig, RIG).unwrap();
    let out_file = dir.path().join("hand.toml");
    let args = ["-q", "calibrate", "hand", "--rig", "sim", "--config", rig.to_str().unwrap()];
    let out: Value = serde_json::from_str(&ok(&[&args[..], &["--frames", "20", "--json"]].concat())).unwrap();
    let err = &out["sim_error_mm_deg"];
    let (mm, deg) = (err[0].as_f64().unwrap(), err[1].as_f64().unwrap());
    println!("calibrate hand (sim, CLI): error {mm:.3} mm, {deg:.4} deg; {}", out["calibration"]);
    assert!(mm < 2.0 && deg < 0.5, "{mm} mm, {deg} deg");
    assert!(out["calibration"]["frames_used"].as_u64().unwrap() >= 15, "{out}");
    writes_the_placement(&args, &out_file);
}

#[test]
fn calibrate_hand_without_a_hand_target_says_so() {
    let err = fails(&["-q", "calibrate", "hand", "--rig", "sim"]);
    assert!(err.contains("[hand_target]"), "{err}");
}

/// Non-default intrinsics of the recording camera (fx 700 px; the default is 600).
const RECORDING_INTRINSICS: &str = "intrinsics = { width = 640, height = 480, fx = 700.0, fy = 700.0, cx = 318.0, cy = 243.0, distortion = [-0.1, 0.02, 0.0004, -0.0003, 0.0] }";

/// The hand target alone: a calibration from this config knows neither the
/// camera's placement nor its intrinsics.
fn target_only() -> String {
    RIG[RIG.find("[hand_target]").expect("RIG has [hand_target]")..].to_string()
}

/// The recording rig: RIG (its non-default placement and its hand target)
/// with RECORDING_INTRINSICS.
fn recording_rig() -> String {
    RIG.replacen("[camera]\n", &format!("[camera]\n{RECORDING_INTRINSICS}\n"), 1)
}

/// Records `frames` simulated frames of the hand target into `name`.mcap;
/// returns the session and the camera's true placement.
fn record(dir: &Path, name: &str, frames: usize, with_calibration: bool) -> (PathBuf, Isometry3<f64>) {
    let config = dir.join("recording_rig.toml");
    std::fs::write(&config, recording_rig()).expect("write the recording rig");
    let out = dir.join(format!("{name}.mcap"));
    let options = HandTargetRecording {
        config: Some(config),
        frames,
        seed: 3,
        with_calibration,
        rgbd: false,
        out: out.clone(),
    };
    let truth = record_hand_target_session(&options).expect("record the hand target session");
    (out, truth)
}

/// Error (mm, degrees) of the JSON result's placement against `truth`.
fn error_of(out: &Value, truth: &Isometry3<f64>) -> (f64, f64) {
    let c = &out["calibration"];
    let v = |key: &str| -> Vec<f64> {
        c[key].as_array().expect("an array").iter().map(|x| x.as_f64().expect("a number")).collect()
    };
    let (t, q) = (v("translation_m"), v("quaternion_xyzw"));
    let estimate = Isometry3::from_parts(
        Translation3::from(Vector3::new(t[0], t[1], t[2])),
        UnitQuaternion::from_quaternion(Quaternion::new(q[3], q[0], q[1], q[2])),
    );
    let mm = (estimate.translation.vector - truth.translation.vector).norm() * 1e3;
    (mm, estimate.rotation.angle_to(&truth.rotation).to_degrees())
}

/// `calibrate hand --session SESSION --config CONFIG`.
fn session_args(session: &Path, config: &Path) -> Vec<String> {
    let (s, c) = (session.to_str().expect("a UTF-8 path"), config.to_str().expect("a UTF-8 path"));
    ["-q", "calibrate", "hand", "--session", s, "--config", c].map(String::from).to_vec()
}

/// Runs `args` with `--frames 5 --out OUT_FILE` and checks the printed line
/// and the written file, a rig config whose `[camera]` holds the placement;
/// returns what was printed.
fn writes_the_placement(args: &[&str], out_file: &Path) -> String {
    let text = ok(&[args, &["--frames", "5", "--out", out_file.to_str().expect("a UTF-8 path")]].concat());
    assert!(text.contains("placement = { kind = \"pose\""), "{text}");
    let written = std::fs::read_to_string(out_file).expect("the --out file");
    let back: toml::Value = toml::from_str(&written).expect("the --out file is TOML");
    assert_eq!(back["camera"]["placement"]["kind"].as_str(), Some("pose"), "{written}");
    text
}

#[test]
fn calibrate_hand_from_a_recorded_session_recovers_the_placement_within_2_mm_and_half_a_degree() {
    let dir = tempdir();
    let (session, truth) = record(dir.path(), "hand", 40, true);
    // Not the default placement: recovering it is not recovering a default.
    let default = slidetrack_sim::camera::SimCameraConfig::default().hand_from_camera().unwrap();
    assert!((truth.translation.vector - default.translation.vector).norm() > 0.01);
    let rig = dir.path().join("target.toml");
    std::fs::write(&rig, target_only()).unwrap();
    let args = session_args(&session, &rig);
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let out: Value = serde_json::from_str(&ok(&[&args[..], &["--frames", "20", "--json"]].concat())).unwrap();
    let (mm, deg) = error_of(&out, &truth);
    println!("calibrate hand (session, CLI): error {mm:.3} mm, {deg:.4} deg; {}", out["calibration"]);
    assert!(mm < 2.0 && deg < 0.5, "{mm} mm, {deg} deg");
    assert_eq!(out["frames_read"].as_u64(), Some(20), "--frames 20 of 40: {out}");
    assert!(out["calibration"]["frames_used"].as_u64().unwrap() >= 15, "{out}");
    assert!(out["intrinsics_from"].as_str().unwrap().contains("/camera/calibration"), "{out}");
    assert!(out["sim_error_mm_deg"].is_null(), "a session has no known truth: {out}");
    let text = writes_the_placement(&args, &dir.path().join("hand.toml"));
    assert!(text.contains("intrinsics: the session's /camera/calibration"), "{text}");
}

#[test]
fn calibrate_hand_from_a_session_without_calibration_takes_the_rig_configs_intrinsics() {
    let dir = tempdir();
    let (session, truth) = record(dir.path(), "uncalibrated", 8, false);
    let rig = dir.path().join("recording_rig.toml");
    let args = session_args(&session, &rig);
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let out: Value = serde_json::from_str(&ok(&[&args[..], &["--json"]].concat())).unwrap();
    assert!(out["intrinsics_from"].as_str().unwrap().contains("[camera]"), "{out}");
    assert_eq!(out["frames_read"].as_u64(), Some(8), "every frame by default: {out}");
    let (mm, deg) = error_of(&out, &truth);
    assert!(mm < 2.0 && deg < 0.5, "{mm} mm, {deg} deg");
}

#[test]
fn calibrate_hand_from_a_session_without_colour_frames_says_so() {
    let dir = tempdir();
    let (session, _) = record(dir.path(), "no_frames", 0, true);
    let rig = dir.path().join("recording_rig.toml");
    let args = session_args(&session, &rig);
    let err = fails(&args.iter().map(String::as_str).collect::<Vec<_>>());
    assert!(err.contains("no_frames.mcap") && err.contains("no colour frames"), "{err}");
}

#[test]
fn calibrate_hand_from_a_session_where_the_target_is_never_seen_says_so() {
    let dir = tempdir();
    let (session, _) = record(dir.path(), "other_marker", 4, true);
    let rig = dir.path().join("other.toml");
    std::fs::write(&rig, target_only().replace("id = 11", "id = 12")).unwrap();
    let args = session_args(&session, &rig);
    let err = fails(&args.iter().map(String::as_str).collect::<Vec<_>>());
    assert!(
        err.contains("other_marker.mcap") && err.contains("marker 12") && err.contains("seen in none"),
        "{err}"
    );
}

/// RIG with a GridBoard (3 x 2 markers of 30 mm, 6 mm apart) as the hand's
/// target instead of the single marker, at the same mount pose.
fn board_rig() -> String {
    RIG.replace(
        "id = 11\nmarker_size_m = 0.05\n",
        "board = { kind = \"grid\", markers_x = 3, markers_y = 2, marker_length_m = 0.03, separation_m = 0.006 }\n",
    )
}

#[test]
fn calibrate_hand_with_a_board_as_the_target_recovers_the_placement_within_2_mm_and_half_a_degree() {
    let dir = tempdir();
    let rig = dir.path().join("board_rig.toml");
    std::fs::write(&rig, board_rig()).unwrap();
    assert!(board_rig().contains("kind = \"grid\"") && !board_rig().contains("id = 11"));
    // Rendered by the simulated camera.
    let args = ["-q", "calibrate", "hand", "--rig", "sim", "--config", rig.to_str().unwrap()];
    let out: Value = serde_json::from_str(&ok(&[&args[..], &["--frames", "20", "--json"]].concat())).unwrap();
    let err = &out["sim_error_mm_deg"];
    let (mm, deg) = (err[0].as_f64().unwrap(), err[1].as_f64().unwrap());
    println!("calibrate hand (sim, GridBoard): error {mm:.3} mm, {deg:.4} deg; {}", out["calibration"]);
    assert!(mm < 2.0 && deg < 0.5, "{mm} mm, {deg} deg");
    assert!(out["calibration"]["frames_used"].as_u64().unwrap() >= 15, "{out}");
    // From a recorded session of the board.
    let config = dir.path().join("recording_rig.toml");
    std::fs::write(
        &config,
        board_rig().replacen("[camera]\n", &format!("[camera]\n{RECORDING_INTRINSICS}\n"), 1),
    )
    .unwrap();
    let session = dir.path().join("board.mcap");
    let options = HandTargetRecording {
        config: Some(config.clone()),
        frames: 20,
        seed: 3,
        with_calibration: true,
        rgbd: false,
        out: session.clone(),
    };
    let truth = record_hand_target_session(&options).expect("record the board session");
    let args = session_args(&session, &config);
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let out: Value = serde_json::from_str(&ok(&[&args[..], &["--json"]].concat())).unwrap();
    let (mm, deg) = error_of(&out, &truth);
    println!("calibrate hand (session, GridBoard): error {mm:.3} mm, {deg:.4} deg");
    assert!(mm < 2.0 && deg < 0.5, "{mm} mm, {deg} deg");
}

#[test]
fn calibrate_hand_from_an_rgbd_cameras_colour_stream_equals_the_camera_image_path() {
    let dir = tempdir();
    let config = dir.path().join("recording_rig.toml");
    std::fs::write(&config, recording_rig()).unwrap();
    // The same frames and intrinsics, once as /camera/image, once as an
    // RGB-D camera's /rgbd/color with /rgbd/calibration.
    let recording = |rgbd: bool, name: &str| {
        let out = dir.path().join(name);
        let options = HandTargetRecording {
            config: Some(config.clone()),
            frames: 20,
            seed: 3,
            with_calibration: true,
            rgbd,
            out: out.clone(),
        };
        (out, record_hand_target_session(&options).expect("record the hand target session"))
    };
    let (image, truth) = recording(false, "image.mcap");
    let (rgbd, _) = recording(true, "rgbd.mcap");
    let info =
        slidetrack_session::SessionInfo::read(&rgbd, slidetrack_session::ReadOptions::default()).unwrap();
    assert!(info.channel("/camera/image").is_none() && info.channel("/rgbd/color").is_some());
    // A config without the recording camera's intrinsics: reading the
    // wrong calibration channel would fall back to the default ones.
    let target = dir.path().join("target.toml");
    std::fs::write(&target, target_only()).unwrap();
    let calibrate = |session: &Path| -> Value {
        let args = session_args(session, &target);
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        serde_json::from_str(&ok(&[&args[..], &["--json"]].concat())).unwrap()
    };
    let (from_image, from_rgbd) = (calibrate(&image), calibrate(&rgbd));
    assert!(from_rgbd["frames_from"].as_str().unwrap().ends_with("/rgbd/color"), "{from_rgbd}");
    assert!(from_rgbd["intrinsics_from"].as_str().unwrap().contains("/rgbd/calibration"), "{from_rgbd}");
    let (mm, deg) = error_of(&from_rgbd, &truth);
    println!("calibrate hand (session, /rgbd/color): error {mm:.3} mm, {deg:.4} deg");
    assert!(mm < 2.0 && deg < 0.5, "{mm} mm, {deg} deg");
    assert_eq!(
        from_rgbd["calibration"], from_image["calibration"],
        "the same frames give the same calibration"
    );
}
