//! `slidetrack vision`: simulate an RGB-D session, track it with ROFT and
//! MaskUKF, track real YCB-Video frames, evaluate; bad input fails cleanly.

mod common;

use std::path::PathBuf;

use common::{fails, ok, tempdir};
use serde_json::Value;
use slidetrack_session::{ReadOptions, SessionInfo};

fn rgbd(rel: &str) -> String {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/testdata/rgbd").join(rel);
    path.to_str().expect("utf-8 path").to_string()
}

#[test]
fn a_simulated_session_is_tracked_by_roft_and_maskukf() {
    let dir = tempdir();
    let session = dir.path().join("fast.mcap");
    let s = session.to_str().unwrap();
    let out = ok(&[
        "-q",
        "vision",
        "simulate",
        "--object",
        "sugar_box",
        "--duration",
        "1.5",
        "--seed",
        "4",
        "--out",
        s,
    ]);
    assert!(out.contains("45 frames"), "{out}");
    let info = SessionInfo::read(&session, ReadOptions::default()).unwrap();
    for topic in ["/rgbd/color", "/rgbd/depth", "/rgbd/mask", "/sim/object"] {
        assert_eq!(info.channel(topic).map(|c| c.message_count), Some(45), "{topic}");
    }
    assert_eq!(info.channel("/vision/pose").map(|c| c.message_count), Some(7));
    assert_eq!(info.channel("/rgbd/calibration").map(|c| c.message_count), Some(1));

    let estimates = dir.path().join("roft.mcap");
    let e = estimates.to_str().unwrap();
    let out = ok(&[
        "-q",
        "vision",
        "track",
        "--tracker",
        "roft",
        "--input",
        s,
        "--model",
        "sim",
        "--out",
        e,
        "--json",
    ]);
    let summary: Value = serde_json::from_str(&out).unwrap();
    assert_eq!(summary["frames"], 45);
    // ROFT starts with the first pose, computed on frame 0 and arriving at frame 6.
    assert_eq!(summary["tracked"], 39);
    assert!(summary["metrics"]["add_auc_percent"].as_f64().unwrap() > 0.0);
    let info = SessionInfo::read(&estimates, ReadOptions::default()).unwrap();
    for topic in ["/estimate/pose/roft", "/estimate/transform/roft", "/estimate/velocity/roft"] {
        assert_eq!(info.channel(topic).map(|c| c.message_count), Some(39), "{topic}");
    }

    let out = ok(&[
        "-q",
        "vision",
        "track",
        "--tracker",
        "maskukf",
        "--input",
        s,
        "--model",
        "sim",
        "--measurements",
        "truth",
        "--init",
        "truth",
        "--json",
    ]);
    let summary: Value = serde_json::from_str(&out).unwrap();
    assert_eq!(summary["tracked"], 45);
}

#[test]
fn maskukf_tracks_the_ycb_video_frames_from_their_labels() {
    let dir = rgbd("ycbv-0000/data/0000");
    let model = rgbd("ycbv-models/061_foam_brick/points.xyz");
    let out = ok(&[
        "-q",
        "vision",
        "track",
        "--tracker",
        "maskukf",
        "--input",
        &dir,
        "--model",
        &model,
        "--init",
        "truth",
        "--json",
    ]);
    let summary: Value = serde_json::from_str(&out).unwrap();
    assert_eq!(summary["tracked"], 10);
    let m = &summary["metrics"];
    assert!(m["adi_auc_percent"].as_f64().unwrap() > 95.0, "{m}");
    assert!(m["max_position_error_cm"].as_f64().unwrap() < 1.0, "{m}");
    assert!(m["max_rotation_error_deg"].as_f64().unwrap() < 5.0, "{m}");
}

#[test]
fn eval_prints_a_table_or_json() {
    let out = ok(&["-q", "vision", "eval", "--objects", "gelatin_box", "--duration", "1.5", "--json"]);
    let rows: Value = serde_json::from_str(&out).unwrap();
    let labels: Vec<&str> = rows.as_array().unwrap().iter().map(|r| r["label"].as_str().unwrap()).collect();
    assert_eq!(labels[..2], ["ROFT", "network"]);
    assert!(labels[2].starts_with("MaskUKF"));
}

#[test]
fn bad_input_fails_with_one_clear_line() {
    let dir = tempdir();
    let missing = dir.path().join("nothing.obj");
    let ycb = rgbd("ycbv-0000/data/0000");
    let line = fails(&[
        "vision",
        "track",
        "--tracker",
        "maskukf",
        "--input",
        &ycb,
        "--model",
        missing.to_str().unwrap(),
        "--object",
        "8",
    ]);
    assert!(line.contains("nothing.obj"), "{line}");
    let line = fails(&[
        "vision",
        "track",
        "--tracker",
        "roft",
        "--input",
        "/no/such/session.mcap",
        "--model",
        "sim",
    ]);
    assert!(line.contains("/no/such/session.mcap"), "{line}");
    let not_rgbd = dir.path().join("x.mcap");
    std::fs::write(&not_rgbd, b"not an mcap file").unwrap();
    let line = fails(&[
        "vision",
        "track",
        "--tracker",
        "roft",
        "--input",
        not_rgbd.to_str().unwrap(),
        "--model",
        "cracker_box",
    ]);
    assert!(line.contains("x.mcap"), "{line}");
    let line = fails(&[
        "vision",
        "simulate",
        "--object",
        "anvil",
        "--out",
        dir.path().join("a.mcap").to_str().unwrap(),
    ]);
    assert!(line.contains("anvil"), "{line}");
}
