//! `slidetrack emulate serial|slcan|xela-server`: the tactile emulators fed
//! by simulated trials, read by the project's own backends as another
//! program would read them (the printed path or URL); the scans show the
//! grasp of the simulated trial.

mod common;

use std::io::{BufRead, BufReader};
use std::process::{Child, Stdio};
use std::sync::Arc;
use std::time::{Duration, Instant};

use common::{SHORT_PROTOCOL, SIM_PATCH_4X4, slidetrack, tempdir};
use nix::sys::signal::{Signal, kill};
use nix::unistd::Pid;
use slidetrack_core::{TactileSource, WallClock, parse_toml};
use slidetrack_drivers::config::TactileDevice;
use slidetrack_experiment::rig_config::RigConfig;

const FINGERS: &str = "fingers = { thumb = { sensor = \"thumb\" }, index = { sensor = \"index\" }, middle = { sensor = \"middle\" } }";

fn rig(tactile: &str) -> String {
    format!(
        "{SHORT_PROTOCOL}{SIM_PATCH_4X4}\n[hw]\nname = \"emulated\"\n[hw.tactile]\n{tactile}\n{FINGERS}\n"
    )
}

/// Runs `slidetrack emulate KIND --config RIG`, returns it and the endpoint it printed.
fn emulate(kind: &str, rig_toml: &str) -> (Child, String, tempfile::TempDir) {
    let dir = tempdir();
    let path = dir.path().join("rig.toml");
    std::fs::write(&path, rig_toml).expect("rig.toml written");
    let mut child = slidetrack()
        .args(["emulate", kind, "--config"])
        .arg(&path)
        .args(["--duration", "5"])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .expect("slidetrack emulate starts");
    let mut line = String::new();
    BufReader::new(child.stdout.take().expect("piped stdout")).read_line(&mut line).expect("the endpoint");
    (child, line.trim().to_string(), dir)
}

fn stop(child: Child) {
    kill(Pid::from_raw(child.id() as i32), Signal::SIGINT).expect("SIGINT sent");
    let out = child.wait_with_output().expect("the emulator exits");
    assert!(out.status.success());
}

/// Reads `source` for 3 s: the scans keep coming at the simulated rate,
/// and the normal force of some taxel grows by the grasp.
fn check_grasp(mut source: Box<dyn TactileSource>) {
    let start = Instant::now();
    let (mut scans, mut first, mut max_rise) = (0u32, None, 0i32);
    while start.elapsed() < Duration::from_secs(3) {
        let sample = source.read().expect("a scan");
        scans += 1;
        let z: Vec<i32> = sample.raw.iter().map(|t| i32::from(t[2])).collect();
        let base = first.get_or_insert_with(|| z.clone());
        max_rise = max_rise.max(z.iter().zip(base.iter()).map(|(a, b)| a - b).max().unwrap_or(0));
    }
    assert!(scans > 150, "{scans} scans in 3 s");
    assert!(max_rise > 100, "the grasp raised the normal counts by {max_rise} at most");
}

fn config(rig_toml: &str) -> TactileDevice {
    let cfg: RigConfig = parse_toml(rig_toml, "rig.toml").expect("a rig config");
    cfg.hw.expect("[hw]").tactile
}

/// Reads the device of `rig_toml` where `slidetrack emulate KIND` serves
/// it, with the backend of the real device; returns the endpoint.
fn read_emulated(kind: &str, rig_toml: &str) -> String {
    let (child, endpoint, _dir) = emulate(kind, rig_toml);
    let device = config(rig_toml).at(&endpoint);
    assert!(!device.is_emulated(), "{device:?} reads the served endpoint");
    let source =
        device.open(None, 100.0, Arc::new(WallClock::start())).expect("the emulator's endpoint opens");
    check_grasp(source);
    stop(child);
    endpoint
}

#[test]
fn the_serial_emulator_streams_simulated_grasps() {
    let _ = read_emulated("serial", &rig("kind = \"serial\"\nport = \"emulated\""));
}

#[test]
fn the_slcan_emulator_streams_simulated_grasps() {
    // `emulate tactile` serves whichever device the table names.
    let _ = read_emulated("tactile", &rig("kind = \"can\"\nslcan = { port = \"emulated\" }"));
}

#[test]
fn the_xela_server_emulator_streams_simulated_grasps() {
    let url = read_emulated("xela-server", &rig("kind = \"xela_ws\"\nurl = \"emulated\""));
    assert!(url.starts_with("ws://127.0.0.1:"), "{url}");
}

#[test]
fn a_config_of_another_device_is_one_clear_error() {
    let text = rig("kind = \"serial\"\nport = \"emulated\"");
    let dir = tempdir();
    let path = dir.path().join("rig.toml");
    std::fs::write(&path, &text).expect("rig.toml written");
    let e = common::fails(&["emulate", "xela-server", "--config", path.to_str().expect("utf-8")]);
    assert!(e.contains("kind = \\\"xela_ws\\\"") || e.contains("kind = \"xela_ws\""), "{e}");
}
