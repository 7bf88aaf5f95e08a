//! A controlled-sliding trial on the rig a lab with a Robotiq gripper and a
//! serial uSkin kit would have, dry-run before touching hardware: the
//! gripper is the simulated one behind the Robotiq Modbus RTU emulator on a
//! pseudo-terminal, the sensors the simulated pads behind the serial
//! emulator, both read and driven through the real backends.
#![expect(clippy::unwrap_used, reason = "test code: a failed unwrap is a failed test")]

mod common;

use std::path::Path;

use common::{SHORT_PROTOCOL, SIM_PATCH_4X4, assert_ended_by_disconnect, ok, slidetrack, tempdir};
use slidetrack_session::{GripperCommand, HandState, ReadOptions, SessionInfo, read_channel};

/// Two 4x4 pads of the simulated gripper read as two serial uSkin modules,
/// and the gripper as a Robotiq 2F-85 on an emulated RS-485 link.
const ROBOTIQ_RIG: &str = "
[sim]
hand = \"gripper\"
[hw]
name = \"robotiq-dry-run\"
[hw.tactile]
kind = \"serial\"
port = \"emulated\"
fingers = { thumb = { sensor = \"left\" }, index = { sensor = \"right\" }, middle = { sensor = \"right\" } }
[[hw.tactile.sensors]]
name = \"left\"
module = 0
finger = \"thumb\"
model = \"uSPa44\"
rows = 4
cols = 4
[[hw.tactile.sensors]]
name = \"right\"
module = 1
finger = \"index\"
model = \"uSPa44\"
rows = 4
cols = 4
[hw.hand]
kind = \"robotiq\"
port = \"emulated\"
";

fn write_rig(dir: &Path, hand_extra: &str) -> String {
    let path = dir.join("rig.toml");
    let text = format!("{SHORT_PROTOCOL}{SIM_PATCH_4X4}{ROBOTIQ_RIG}{hand_extra}");
    std::fs::write(&path, text).unwrap();
    path.to_str().unwrap().to_string()
}

fn collect(rig: &str, out: &Path, duration_s: &str) -> std::process::Output {
    slidetrack()
        .args(["-q", "collect", "--rig", "hw", "--config", rig, "--object", "box", "--seed", "2"])
        .args(["--duration", duration_s, "--no-camera", "--out", out.to_str().unwrap()])
        .output()
        .unwrap()
}

#[test]
fn a_trial_through_the_emulated_robotiq_grips_slides_and_releases() {
    let dir = tempdir();
    let rig = write_rig(dir.path(), "");
    let out = dir.path().join("out");
    let output = collect(&rig, &out, "8");
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(output.status.success(), "{stderr}");
    let file = out.join("box-s2-t000.mcap");
    let info = SessionInfo::read(&file, ReadOptions::default()).unwrap();
    assert_eq!(info.metadata["slidetrack.outcome"]["completed"], "true", "{:?}", info.metadata);

    // The protocol drove the gripper with position requests over Modbus.
    let requests: Vec<GripperCommand> = read_channel::<GripperCommand>(&file, ReadOptions::default())
        .unwrap()
        .into_iter()
        .map(|(_, r)| r)
        .collect();
    let deepest = requests.iter().map(|r| r.position).max().unwrap();
    assert!(deepest > 100, "the gripper closed on the object: deepest request {deepest}");
    // It varied the grasp during the cycles (the PI law at work), then released.
    let distinct: std::collections::BTreeSet<u16> = requests.iter().map(|r| r.position).collect();
    assert!(distinct.len() > 5, "{distinct:?}");

    // The gripper's own status came back over the link: it held the object.
    let states = read_channel::<HandState>(&file, ReadOptions::default()).unwrap();
    let held = states.iter().filter(|(_, s)| s.gripper.is_some_and(|g| g.activated && g.object == 2)).count();
    assert!(held > 100, "{held} statuses with gOBJ = 2 of {}", states.len());
    let (_, last) = states.last().unwrap();
    assert!(last.opening.unwrap() > 0.05, "the gripper opened at the end: {last:?}");
}

#[test]
fn a_gripper_fault_mid_trial_ends_it_with_a_release_and_a_readable_session() {
    let dir = tempdir();
    let rig = write_rig(dir.path(), "[hw.hand.emulator]\nfault_code = 14\nfault_after_s = 4.0\n");
    let out = dir.path().join("out");
    let output = collect(&rig, &out, "20");
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(1), "{stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert!(stderr.to_lowercase().contains("overcurrent"), "the fault is named: {stderr}");
    assert!(stderr.contains("released"), "{stderr}");
    let file = out.join("box-s2-t000.mcap");
    let info = SessionInfo::read(&file, ReadOptions::default()).expect("a finished, readable session");
    assert!(!info.truncated);
    assert_eq!(info.metadata["slidetrack.outcome"]["completed"], "false");
    let events = ok(&["export", file.to_str().unwrap(), "--channel", "/protocol/events"]);
    assert!(events.lines().last().unwrap().contains("aborted"), "{events}");
}

#[test]
fn an_unplugged_gripper_mid_trial_ends_it_with_a_readable_session() {
    let dir = tempdir();
    let rig = write_rig(dir.path(), "[hw.hand.emulator]\nunplug_after_s = 4.0\n");
    let out = dir.path().join("out");
    let output = collect(&rig, &out, "20");
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(1), "{stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert!(stderr.contains("disconnected"), "{stderr}");
    assert_ended_by_disconnect(&out.join("box-s2-t000.mcap"), 100..=1000);
}
