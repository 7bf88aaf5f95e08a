//! A recording killed mid-trial stays readable up to its last complete chunk.

mod common;

use std::time::{Duration, Instant};

use common::{fails, ok, slidetrack, tempdir};

#[test]
fn a_killed_recording_is_readable_up_to_its_last_complete_chunk() {
    let dir = tempdir();
    let mut child = slidetrack()
        .args(["-q", "collect", "--object", "box", "--duration", "60", "--no-camera", "--realtime", "--out"])
        .arg(dir.path())
        .spawn()
        .expect("collect starts");
    let file = dir.path().join("box-s1-t000.mcap");
    // The recorder closes a chunk at least every second; wait for a few.
    let start = Instant::now();
    while start.elapsed() < Duration::from_secs(4) {
        std::thread::sleep(Duration::from_millis(100));
    }
    child.kill().expect("SIGKILL");
    child.wait().expect("reaped");
    let path = file.to_str().unwrap();
    let e = fails(&["info", path]);
    assert!(e.contains("truncated"), "{e}");
    let info: serde_json::Value = serde_json::from_str(&ok(&["info", path, "--recover", "--json"])).unwrap();
    assert_eq!(info["truncated"], true);
    let raw = info["channels"].as_array().unwrap().iter().find(|c| c["topic"] == "/tactile/raw").unwrap();
    let n = raw["messages"].as_u64().unwrap();
    // About 100 scans a second for 4 s, minus the chunk still open when killed.
    assert!((150..=450).contains(&n), "{n} tactile scans recovered");
    let csv = ok(&["export", path, "--channel", "/tactile/raw", "--recover"]);
    assert_eq!(csv.lines().count() as u64, n + 1);
}

#[test]
fn ctrl_c_releases_the_hand_and_leaves_a_complete_session() {
    use nix::sys::signal::{Signal, kill};
    use nix::unistd::Pid;
    let dir = tempdir();
    let child = slidetrack()
        .args([
            "-q",
            "collect",
            "--object",
            "bottle",
            "--duration",
            "60",
            "--no-camera",
            "--realtime",
            "--out",
        ])
        .arg(dir.path())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("collect starts");
    std::thread::sleep(Duration::from_secs(3));
    kill(Pid::from_raw(child.id() as i32), Signal::SIGINT).expect("SIGINT");
    let out = child.wait_with_output().expect("collect ends");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("interrupted"), "{stderr}");
    // Complete: readable without --recover, with its outcome.
    let file = dir.path().join("bottle-s1-t000.mcap");
    let info: serde_json::Value =
        serde_json::from_str(&ok(&["info", file.to_str().unwrap(), "--json"])).unwrap();
    assert_eq!(info["truncated"], false);
    let outcome = &info["metadata"]["slidetrack.outcome"];
    assert_eq!(outcome["completed"], "false");
    assert!(outcome["abort_reason"].as_str().unwrap().contains("interrupted"), "{outcome}");
    let events = ok(&["export", file.to_str().unwrap(), "--channel", "/protocol/events"]);
    assert!(events.contains("aborted"), "{events}");
}
