//! `slidetrack calibrate hand` on the simulated rig with a known, non-default
//! camera placement: the judged recovery (2 mm, 0.5 degree), the output file
//! read back as a rig config, and the refusal without a hand target.

mod common;

use common::{fails, ok, tempdir};
use serde_json::Value;

const RIG: &str = r#"
[camera]
placement = { kind = "look_at", position_m = [0.28, 0.06, 0.14], look_at_m = [0.08, -0.01, 0.0], up_in_hand = [0.1, 0.0, 1.0] }

[hand_target]
dictionary = "DICT_6X6_250"
id = 11
marker_size_m = 0.05
hand_from_target = { translation_m = [0.1024, 0.0069, 0.0086], quaternion_xyzw = [0.351615, 0.452679, 0.671449, 0.469686] }
"#;

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
    let text = ok(&[&args[..], &["--frames", "5", "--out", out_file.to_str().unwrap()]].concat());
    assert!(text.contains("placement = { kind = \"pose\""), "{text}");
    // The written file is a valid rig config whose [camera] holds the placement.
    let written = std::fs::read_to_string(&out_file).unwrap();
    let back: toml::Value = toml::from_str(&written).unwrap();
    assert_eq!(back["camera"]["placement"]["kind"].as_str(), Some("pose"), "{written}");
}

#[test]
fn calibrate_hand_without_a_hand_target_says_so() {
    let err = fails(&["-q", "calibrate", "hand", "--rig", "sim"]);
    assert!(err.contains("[hand_target]"), "{err}");
}
