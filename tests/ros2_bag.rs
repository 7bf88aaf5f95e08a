//! `export --ros2-bag` end to end: an independent ROS 2 bag reader (the
//! `rosbags` package, tests/python/check_ros2_bag.py) reads the bags of a
//! tracked session (dEKF and marker estimates, vision poses, velocities and transforms,
//! images, camera info, hand state) and of a session with 4x4 taxel patches,
//! and finds the sessions' values; errors are one line naming the file.

mod common;

use std::path::Path;

use common::rosbags::{export_and_check, python_with_rosbags};
use common::{SIM_PATCH_4X4, fails, ok, tempdir, trained};

fn s(p: &Path) -> &str {
    p.to_str().expect("utf-8 path")
}

fn count(summary: &serde_json::Value, topic: &str) -> u64 {
    summary[topic].as_u64().unwrap_or(0)
}

#[test]
fn rosbags_reads_a_tracked_session_with_the_sessions_values() {
    let Some(python) = python_with_rosbags() else { return };
    let dir = tempdir();
    let (_, model) = trained(dir.path());
    let session = dir.path().join("tracked.mcap");
    ok(&[
        "-q",
        "track",
        "--model",
        s(&model),
        "--duration",
        "3",
        "--seed",
        "7",
        "--vision",
        "maskukf",
        "--out",
        s(&session),
    ]);
    let summary = export_and_check(&python, &session);
    for topic in [
        "/tactile/raw",
        "/hand/state",
        "/estimate/dekf",
        "/estimate/aruco",
        "/camera/image",
        "/camera/calibration",
        "/estimate/transform/maskukf",
        "/estimate/pose/maskukf",
        "/estimate/velocity/maskukf",
        "/estimate/odometry/maskukf",
    ] {
        assert!(count(&summary, topic) > 0, "{topic}: {summary}");
    }
    assert!(count(&summary, "/estimate/dekf") > 100, "{summary}");
}

#[test]
fn every_taxel_of_a_4x4_patch_session_arrives() {
    let Some(python) = python_with_rosbags() else { return };
    let dir = tempdir();
    let config = dir.path().join("rig.toml");
    std::fs::write(&config, SIM_PATCH_4X4).expect("write rig.toml");
    let session = common::collect(dir.path(), "box", 3, 2.0, &["--no-camera", "--config", s(&config)]);
    let summary = export_and_check(&python, &session);
    assert!(count(&summary, "/tactile/raw") > 100, "{summary}");
}

#[test]
fn a_file_that_is_not_a_session_is_one_line_naming_it() {
    let dir = tempdir();
    let bogus = dir.path().join("notes.mcap");
    std::fs::write(&bogus, "not mcap").expect("write");
    let err = fails(&["export", s(&bogus), "--ros2-bag", s(&dir.path().join("bag.mcap"))]);
    assert!(err.contains("notes.mcap") && err.contains("not an MCAP file"), "{err}");
    assert_eq!(err.trim().lines().count(), 1, "{err}");
}
