//! `slidetrack emulate robotiq` driven by an independent Modbus RTU client
//! (Python minimalmodbus, pinned in scripts/setup.sh) through its
//! pseudo-terminal: activation, close onto an object, open; the status
//! registers follow the Robotiq register map.

mod common;

use std::io::{BufRead, BufReader};
use std::process::{Child, Command, Stdio};

use common::{python, slidetrack};
use nix::sys::signal::{Signal, kill};
use nix::unistd::Pid;

/// The emulator as a child process and the port it printed.
fn emulate(args: &[&str]) -> (Child, String) {
    let mut child = slidetrack()
        .args(["emulate", "robotiq"])
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("slidetrack emulate starts");
    let stdout = child.stdout.take().expect("piped stdout");
    let mut line = String::new();
    BufReader::new(stdout).read_line(&mut line).expect("the port on stdout");
    let port = line.trim().to_string();
    assert!(port.starts_with("/dev/pts/"), "{port:?}");
    (child, port)
}

/// Ctrl-C ends the emulator cleanly; returns its stderr.
fn interrupt(child: Child) -> String {
    kill(Pid::from_raw(child.id() as i32), Signal::SIGINT).expect("SIGINT sent");
    let out = child.wait_with_output().expect("the emulator exits");
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(out.status.success(), "{stderr}");
    stderr
}

fn registers(v: &serde_json::Value) -> Vec<[u16; 3]> {
    v.as_array()
        .expect("a list of statuses")
        .iter()
        .map(|r| {
            let r: Vec<u16> =
                r.as_array().expect("3 registers").iter().map(|x| x.as_u64().expect("u16") as u16).collect();
            [r[0], r[1], r[2]]
        })
        .collect()
}

#[test]
fn an_independent_modbus_client_activates_closes_and_opens_the_emulated_gripper() {
    let (child, port) = emulate(&["--object-width-mm", "40", "--activation-s", "0.3"]);
    let out = Command::new(python())
        .arg(concat!(env!("CARGO_MANIFEST_DIR"), "/tests/python/robotiq_client.py"))
        .arg(&port)
        .output()
        .expect("python runs");
    let stderr = interrupt(child);
    assert!(out.status.success(), "client failed:\n{}", String::from_utf8_lossy(&out.stderr));
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).expect("JSON from the client");

    // Activation: gACT = 1 with gSTA = 1 (0x11), then gSTA = 3 (0x31), as the manual's example.
    let activating = registers(&report["activating"]);
    assert_eq!(activating.first().map(|r| r[0] >> 8), Some(0x11), "{activating:?}");
    assert_eq!(activating.last().map(|r| r[0] >> 8), Some(0x31), "{activating:?}");
    // Closing onto a 40 mm object: gOBJ = 2 (0xB9), gPR = 255, gPO = 45/85 of 255.
    let closed = *registers(&report["closing"]).last().expect("a status");
    assert_eq!(closed[0] >> 8, 0xB9, "{closed:04x?}");
    assert_eq!(closed[1], 0x00FF, "no fault, gPR echo 255");
    assert_eq!(closed[2] >> 8, 135, "gPO");
    assert!(closed[2] & 0xFF > 0, "gCU while holding");
    // Opening (FC6 rPR = 0, read with FC4): at the request (0xF9), gPO = 0.
    let opened = *registers(&report["opening"]).last().expect("a status");
    assert_eq!((opened[0] >> 8, opened[1], opened[2] >> 8), (0xF9, 0x0000, 0));
    assert_eq!(report["request_echo"], serde_json::json!([0x0900, 0x0000, 0xFFFF]));
    // The manual: no exception responses; a bad address gets silence.
    assert_eq!(report["bad_address"], "no response");
    assert!(stderr.contains("emulated Robotiq 2f85 (device id 9, an object 40 mm wide)"), "{stderr}");
}

#[test]
fn with_exceptions_on_a_bad_address_is_refused() {
    let (child, port) = emulate(&["--exceptions", "--unpaced", "--activation-s", "0"]);
    let script = format!(
        "import minimalmodbus\ng = minimalmodbus.Instrument({port:?}, 9)\ng.serial.timeout = 0.3\n\
         try:\n    g.read_registers(0x0000, 3)\nexcept minimalmodbus.IllegalRequestError:\n    print('illegal')\n\
         print(g.read_registers(0x07D0, 3))\n"
    );
    let out = Command::new(python()).args(["-c", &script]).output().expect("python runs");
    interrupt(child);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert_eq!(stdout.lines().collect::<Vec<_>>(), ["illegal", "[0, 0, 0]"], "reset gripper: all zero");
}

#[test]
fn record_watches_the_gripper_on_hand_state_without_commanding_it() {
    let dir = common::tempdir();
    let rig = dir.path().join("rig.toml");
    let text = "[hw]\nname = \"robotiq-watch\"\n[hw.camera]\nkind = \"none\"\n[hw.hand]\nkind = \"robotiq\"\n\
                port = \"emulated\"\nmodel = \"hand-e\"\n";
    std::fs::write(&rig, text).expect("rig.toml written");
    let file = dir.path().join("watch.mcap");
    let (rig, f) = (rig.to_str().expect("utf-8"), file.to_str().expect("utf-8"));
    common::ok(&["-q", "record", "--rig", "hw", "--config", rig, "--duration", "1", "--out", f]);
    let read = slidetrack_session::ReadOptions::default();
    let hand =
        slidetrack_session::read_channel::<slidetrack_session::HandState>(&file, read).expect("/hand/state");
    assert!(hand.len() > 50, "{} hand states in 1 s", hand.len());
    for (_, h) in &hand {
        let g = h.gripper.expect("the gripper's registers");
        // Watched, never activated: gSTA = 0, fingers open (Hand-E: 50 mm).
        assert!(!g.activated && g.fault == 0 && g.requested == 0, "{g:?}");
        assert!(h.opening.is_some_and(|o| (o - 0.050).abs() < 1e-9), "{h:?}");
    }
}
