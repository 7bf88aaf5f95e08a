//! `label --hand-calibration`: a simulated session recorded with a
//! non-default camera placement, labelled in the hand frame with the
//! calibration `calibrate hand` estimates on the same rig. The sliding axis
//! then comes from the hand's geometry; the ground truth must be at least as
//! good as with the axis fitted to the marker's track, and a calibration
//! rotated by 30 degrees must make it measurably worse.

mod common;

use std::path::Path;

use common::{collect, fails, ok, tempdir};
use nalgebra::{Quaternion, UnitQuaternion, Vector3};
use serde_json::Value;
use slidetrack_session::{ReadOptions, SessionInfo};

// The camera off the default placement, and the hand's target.
use common::HAND_TARGET_RIG as RIG;

/// `label FILE EXTRA... --dry-run --json`: the session's summary.
fn label(file: &Path, extra: &[&str]) -> Value {
    let args =
        [&["-q", "label", file.to_str().expect("a UTF-8 path"), "--dry-run", "--json"][..], extra].concat();
    let out: Value = serde_json::from_str(&ok(&args)).expect("JSON");
    out[0].clone()
}

fn position_rmse_mm(summary: &Value) -> f64 {
    summary["rmse"]["position_m"].as_f64().expect("an RMSE against /sim/truth") * 1e3
}

/// `hand.toml`'s placement turned by `degrees` about the hand's x axis
/// (across the sliding axis), written to `path`.
fn rotated_calibration(hand: &Path, degrees: f64, path: &Path) {
    let text = std::fs::read_to_string(hand).expect("the calibration");
    let mut value: toml::Value = toml::from_str(&text).expect("TOML");
    let placement = &mut value["camera"]["placement"];
    let q: Vec<f64> = placement["quaternion_xyzw"]
        .as_array()
        .expect("a quaternion")
        .iter()
        .map(|v| v.as_float().expect("a number"))
        .collect();
    let t: Vec<f64> = placement["translation_m"]
        .as_array()
        .expect("a translation")
        .iter()
        .map(|v| v.as_float().expect("a number"))
        .collect();
    let turn = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), degrees.to_radians());
    let rotation = turn * UnitQuaternion::from_quaternion(Quaternion::new(q[3], q[0], q[1], q[2]));
    let translation = turn * Vector3::new(t[0], t[1], t[2]);
    let c = rotation.coords;
    placement["quaternion_xyzw"] = toml::Value::try_from([c.x, c.y, c.z, c.w]).expect("a TOML array");
    placement["translation_m"] =
        toml::Value::try_from([translation.x, translation.y, translation.z]).expect("a TOML array");
    std::fs::write(path, toml::to_string(&value).expect("TOML")).expect("write the rotated calibration");
}

#[test]
fn labelling_in_the_hand_frame_recovers_the_sliding_at_least_as_well_as_the_fitted_axis() {
    let dir = tempdir();
    let rig = dir.path().join("rig.toml");
    std::fs::write(&rig, RIG).unwrap();
    let rig_arg = rig.to_str().unwrap();
    let file = collect(dir.path(), "box", 3, 20.0, &["--config", rig_arg]);
    let hand = dir.path().join("hand.toml");
    let hand_arg = hand.to_str().unwrap();
    ok(&[
        "-q",
        "calibrate",
        "hand",
        "--rig",
        "sim",
        "--config",
        rig_arg,
        "--frames",
        "20",
        "--out",
        hand_arg,
    ]);

    let fitted = label(&file, &["--axis", "estimate"]);
    let in_hand = label(&file, &["--hand-calibration", hand_arg]);
    let wrong_file = dir.path().join("wrong.toml");
    rotated_calibration(&hand, 30.0, &wrong_file);
    let wrong = label(&file, &["--hand-calibration", wrong_file.to_str().unwrap()]);
    let (fitted_mm, in_hand_mm, wrong_mm) =
        (position_rmse_mm(&fitted), position_rmse_mm(&in_hand), position_rmse_mm(&wrong));
    println!(
        "position RMSE vs /sim/truth: fitted axis {fitted_mm:.4} mm, hand calibration {in_hand_mm:.4} mm, \
         calibration turned 30 deg {wrong_mm:.4} mm"
    );
    assert!(
        in_hand_mm <= fitted_mm * 1.05 + 0.005,
        "{in_hand_mm} mm against the fitted axis's {fitted_mm} mm"
    );
    assert!(in_hand_mm < 0.16, "{in_hand_mm} mm");
    assert!(wrong_mm > 3.0 * in_hand_mm && wrong_mm > 0.3, "a wrong calibration: {wrong_mm} mm");

    // The output says where the axis came from; the axis is the default
    // gripper's, down; the contact frame is the geometry's.
    assert!(in_hand["axis_from"].as_str().unwrap().contains("hand calibration"), "{in_hand}");
    assert!(fitted.get("hand_frame").is_none() && fitted.get("axis_from").is_none(), "{fitted}");
    let h = &in_hand["hand_frame"];
    let axis: Vec<f64> =
        h["sliding_axis_in_hand"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect();
    assert!((axis[0].abs() + axis[1].abs() + (axis[2] + 1.0).abs()) < 1e-12, "{h}");
    assert_eq!(h["geometry_from"].as_str(), Some("the default [hand_geometry]"), "{h}");
    assert_eq!(in_hand["in_hand"]["contact"]["normal"], serde_json::json!([0.0, 1.0, 0.0]), "{in_hand}");

    // Written: the ground truth's record names the source.
    ok(&["-q", "label", file.to_str().unwrap(), "--hand-calibration", hand_arg]);
    let info = SessionInfo::read(&file, ReadOptions::default()).unwrap();
    let channel = info.channels.iter().find(|c| c.topic == "/ground_truth/sliding").unwrap();
    let params: Value = serde_json::from_str(&channel.metadata["parameters"]).unwrap();
    assert!(params["measurement_source"].as_str().unwrap().contains("hand geometry"), "{params}");
}

#[test]
fn a_bad_hand_calibration_is_refused_naming_the_file() {
    let dir = tempdir();
    let bad = dir.path().join("bad.toml");
    std::fs::write(&bad, "[camera]\n").unwrap();
    let e = fails(&["label", "x.mcap", "--hand-calibration", bad.to_str().unwrap()]);
    assert!(e.contains("bad.toml") && e.contains("[camera] placement"), "{e}");
}
