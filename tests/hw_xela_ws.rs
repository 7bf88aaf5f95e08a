//! `collect --rig hw` with `kind = "xela_ws"`: (a) the simulated rig behind
//! a local `xela_server` emulator (`url = "emulated"`, closed loop), and (b)
//! a local server replaying the published message examples at their timing
//! (open loop, simulated hand); faults: a server gone for good, a short
//! outage, malformed JSON, counter gaps, a wrong model.
#![cfg(all(feature = "devices", target_os = "linux"))]

mod common;

use std::path::{Path, PathBuf};
use std::time::Duration;

use common::{SHORT_PROTOCOL, SIM_PATCH_4X4, assert_ended_by_disconnect, ok, slidetrack, tempdir};
use serde_json::Value;
use slidetrack_drivers::xela_ws::backend::{EmulatedMessage, XelaWsEmulator, XelaWsEmulatorConfig};
use slidetrack_session::{
    ReadOptions, SessionInfo, TactileCalibrated, TactileDecoder, TactileDeviceTime, TactileRaw, TaxelLayout,
    read_channel,
};

/// The simulated 4x4 patches behind the emulator, as server sensors 1-3.
const XELA_EMULATED: &str = "
[hw]
name = \"emulated-xela\"
[hw.tactile]
kind = \"xela_ws\"
url = \"emulated\"
fingers = { thumb = { sensor = \"thumb\" }, index = { sensor = \"index\" }, middle = { sensor = \"middle\" } }
[hw.hand]
kind = \"sim\"
[hw.camera]
kind = \"sim\"
";

/// What the fingers of [`two_patches`] read.
const TWO_PATCH_FINGERS: &str = "fingers = { thumb = { sensor = \"left\" }, index = { sensor = \"right\", taxel = 5 }, middle = { sensor = \"right\" } }";

/// Two uSPa44 patches (server sensors 1 and 2) of a parallel gripper.
fn two_patches(url: &str) -> String {
    two_patches_reading(url, TWO_PATCH_FINGERS)
}

/// [`two_patches`] with the `fingers` line `fingers` (empty: none).
fn two_patches_reading(url: &str, fingers: &str) -> String {
    format!(
        "{SHORT_PROTOCOL}
[hw]
name = \"xela-replay\"
[hw.tactile]
kind = \"xela_ws\"
url = \"{url}\"
{fingers}
[[hw.tactile.sensors]]
name = \"left\"
sensor = 1
finger = \"thumb\"
model = \"uSPa44\"
rows = 4
cols = 4
[[hw.tactile.sensors]]
name = \"right\"
sensor = 2
finger = \"index\"
model = \"uSPa44\"
rows = 4
cols = 4
[hw.hand]
kind = \"sim\"
[hw.camera]
kind = \"none\"
"
    )
}

fn write(dir: &Path, text: &str) -> String {
    let path = dir.join("rig.toml");
    std::fs::write(&path, text).expect("rig.toml written");
    path.to_str().expect("a UTF-8 path").to_string()
}

fn emulated_rig(dir: &Path, emulator: &str) -> String {
    write(dir, &format!("{SHORT_PROTOCOL}{SIM_PATCH_4X4}{XELA_EMULATED}\n[hw.tactile.emulator]\n{emulator}"))
}

/// Runs `collect --rig hw` (2 s of cycles, no camera), returns (exit code, stderr, file).
fn collect(rig: &str, out: &Path) -> (Option<i32>, String, PathBuf) {
    let output = slidetrack()
        .args(["-q", "collect", "--rig", "hw", "--config", rig, "--object", "box", "--duration", "2"])
        .args(["--seed", "3", "--no-camera", "--out", out.to_str().expect("utf-8")])
        .output()
        .expect("slidetrack runs");
    let stderr = String::from_utf8_lossy(&output.stderr).into_owned();
    assert!(!stderr.contains("panicked"), "{stderr}");
    (output.status.code(), stderr, out.join("box-s3-t000.mcap"))
}

fn last_counters(file: &Path) -> TactileDecoder {
    let counters = read_channel::<TactileDecoder>(file, ReadOptions::default()).expect("a readable session");
    counters.last().expect("decoder counters recorded").1
}

/// A fixture message with its counter and times moved to message `k` of a
/// stream at `period_s`, and `calibrated` set to `calibrated` if given.
fn fixture_message(fixture: &Value, k: u64, period_s: f64, calibrated: Option<&Value>) -> Value {
    let mut m = fixture.clone();
    let shift = k as f64 * period_s;
    m["message"] = Value::from(fixture["message"].as_u64().expect("as the fixture has it") + k);
    m["time"] = Value::from(fixture["time"].as_f64().expect("as the fixture has it") + shift);
    let obj = m.as_object_mut().expect("as the fixture has it");
    for (key, sensor) in obj.iter_mut() {
        if key.bytes().all(|b| b.is_ascii_digit()) {
            sensor["time"] = Value::from(sensor["time"].as_f64().expect("as the fixture has it") + shift);
            if let Some(c) = calibrated {
                sensor["calibrated"] = c.clone();
            }
        }
    }
    m
}

/// `count` messages made of a fixture, 10 ms apart, sent at the pace of
/// their `time` fields, `calibrated` replaced when given.
fn replay(file: &str, count: u64, calibrated: Option<&Value>) -> Vec<EmulatedMessage> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("drivers/src/xela_ws/fixtures").join(file);
    let fixture: Value = serde_json::from_str(&std::fs::read_to_string(path).expect("as the fixture has it"))
        .expect("as the fixture has it");
    let messages: Vec<Value> = (0..count).map(|k| fixture_message(&fixture, k, 0.01, calibrated)).collect();
    let mut previous = messages[0]["time"].as_f64().expect("as the fixture has it");
    messages
        .iter()
        .map(|m| {
            let t = m["time"].as_f64().expect("as the fixture has it");
            let delay = Duration::from_secs_f64((t - previous).max(0.0));
            previous = t;
            EmulatedMessage { delay, text: m.to_string() }
        })
        .collect()
}

#[test]
fn the_emulated_server_closes_the_loop_counts_malformed_messages_and_gaps() {
    let dir = tempdir();
    let rig = emulated_rig(dir.path(), "malformed_every = 50\ngap_every = 70\n");
    let (code, stderr, file) = collect(&rig, &dir.path().join("hw"));
    assert_eq!(code, Some(0), "{stderr}");
    let info = SessionInfo::read(&file, ReadOptions::default()).unwrap();
    assert_eq!(info.metadata["slidetrack.outcome"]["completed"], "true");
    let raw_channel = info.channels.iter().find(|c| c.topic == "/tactile/raw").unwrap();
    let layout = TaxelLayout::from_channel_metadata(&raw_channel.metadata).unwrap().unwrap();
    assert!(layout.device.starts_with("ws://127.0.0.1:"), "{}", layout.device);

    // The simulated rig's own session: while the hand is open the values
    // do not depend on timing, so the JSON carried exactly its scans.
    let sim_rig = write(dir.path(), &format!("{SHORT_PROTOCOL}{SIM_PATCH_4X4}"));
    let sim_out = dir.path().join("sim");
    let args = ["-q", "collect", "--config", &sim_rig, "--object", "box", "--duration", "2", "--seed", "3"];
    ok(&[&args[..], &["--no-camera", "--out", sim_out.to_str().unwrap()]].concat());
    let sim =
        read_channel::<TactileRaw>(&dir.path().join("sim/box-s3-t000.mcap"), ReadOptions::default()).unwrap();
    let hw = read_channel::<TactileRaw>(&file, ReadOptions::default()).unwrap();
    assert_eq!(hw[0].1.sensors.iter().map(|s| s.taxels.len()).sum::<usize>(), 48);
    for ((_, a), (_, b)) in hw.iter().zip(&sim).take(45) {
        assert_eq!(a, b);
    }
    // The message counter is the sequence: one skipped after every 70th scan.
    let skips = hw.windows(2).filter(|w| w[1].1.sequence != w[0].1.sequence + 1).count() as u64;
    let c = last_counters(&file);
    let scans = hw.len() as u64;
    assert_eq!((c.frames, c.gaps), (scans, skips), "{c:?}");
    assert!(skips >= scans / 70 - 1 && skips >= 3, "{skips} gaps in {scans} scans");
    assert!(c.incomplete_scans >= scans / 50 - 1 && c.incomplete_scans >= 5, "malformed counted: {c:?}");
    // The server's time beside every scan; no calibrated forces from the simulator.
    let times = read_channel::<TactileDeviceTime>(&file, ReadOptions::default()).unwrap();
    assert_eq!(times.len(), hw.len());
    assert!(times.iter().zip(&hw).all(|((ta, m), (tb, r))| ta == tb && m.sequence == r.sequence));
    assert!(!info.channels.iter().any(|c| c.topic == "/tactile/calibrated"));
}

#[test]
fn fixtures_replayed_at_their_timing_keep_every_taxel_and_the_calibrated_forces() {
    let dir = tempdir();
    // About 12 s of messages; a malformed one, a counter gap and a dropped
    // connection (the client reconnects, the script goes on) on the way.
    let mut messages = replay("v177_list_uspa44_x2.json", 1200, None);
    messages
        .insert(100, EmulatedMessage { delay: Duration::ZERO, text: "{\"message\": 12, \"1\": [".into() });
    messages.remove(300); // a counter skipped
    let mut script = XelaWsEmulatorConfig { messages, ..XelaWsEmulatorConfig::texts(vec![], Duration::ZERO) };
    script.disconnect_after = vec![400];
    let server = XelaWsEmulator::start(script).unwrap();
    let rig = write(dir.path(), &two_patches(&server.url()));
    let (code, stderr, file) = collect(&rig, &dir.path().join("out"));
    assert_eq!(code, Some(0), "{stderr}");
    assert!(server.connections() >= 2, "the client reconnected");

    let fixture: Value =
        serde_json::from_str(include_str!("../drivers/src/xela_ws/fixtures/v177_list_uspa44_x2.json"))
            .unwrap();
    let counts = |s: &str| -> Vec<u16> {
        fixture[s]["data"].as_array().unwrap().iter().map(|v| v.as_u64().unwrap() as u16).collect()
    };
    let want: Vec<u16> = [counts("1"), counts("2")].concat();
    assert_eq!(want.len(), 96);
    let raw = read_channel::<TactileRaw>(&file, ReadOptions::default()).unwrap();
    assert!(raw.len() > 300, "{} scans", raw.len());
    for (_, m) in &raw {
        let names: Vec<&str> = m.sensors.iter().map(|s| s.name.as_str()).collect();
        assert_eq!(names, ["left", "right"]);
        let got: Vec<u16> = m.sensors.iter().flat_map(|s| &s.taxels).flat_map(|t| t.to_array()).collect();
        assert_eq!(got, want, "all 96 values, in the server's order");
    }
    let c = last_counters(&file);
    assert_eq!((c.incomplete_scans, c.gaps), (1, 1), "{c:?}");

    // Calibrated forces on their own channel, in N, as the server sent them.
    let forces = read_channel::<TactileCalibrated>(&file, ReadOptions::default()).unwrap();
    assert_eq!(forces.len(), raw.len());
    let f0 = &forces[0].1.sensors[0].taxels[0];
    let cal = &fixture["1"]["calibrated"];
    assert_eq!([f0.x, f0.y, f0.z], [0, 1, 2].map(|i| cal[i].as_f64().unwrap()));
    let times = read_channel::<TactileDeviceTime>(&file, ReadOptions::default()).unwrap();
    let t0 = fixture["time"].as_f64().unwrap();
    assert!(times.iter().all(|(_, m)| m.device_time_s >= t0 && m.device_time_s < t0 + 13.0));

    // End to end: export writes the 96 values of a scan; info lists the channels.
    let path = file.to_str().unwrap();
    let csv = ok(&["export", path, "--channel", "/tactile/raw"]);
    let header: Vec<&str> = csv.lines().next().unwrap().split(',').collect();
    let values = header.iter().filter(|h| h.contains(".taxels.")).count();
    assert_eq!(values, 96, "{header:?}");
    let row: Vec<&str> = csv.lines().nth(1).unwrap().split(',').collect();
    assert_eq!(row.len(), header.len());
    let cal_csv = ok(&["export", path, "--channel", "/tactile/calibrated"]);
    assert_eq!(cal_csv.lines().next().unwrap().split(',').filter(|h| h.contains(".taxels.")).count(), 96);
    let info = ok(&["info", path]);
    for topic in ["/tactile/raw", "/tactile/calibrated", "/tactile/device_time", "/tactile/decoder"] {
        assert!(info.contains(topic), "{info}");
    }
}

#[test]
fn two_pads_need_no_fingers_table() {
    // Each sensor names its finger: the thumb reads the left pad, index and
    // middle the right one, taxel 0 (before, the run refused to start: the
    // default table looked for sensors named after the fingers).
    let dir = tempdir();
    let server = XelaWsEmulator::start(XelaWsEmulatorConfig {
        messages: replay("v177_list_uspa44_x2.json", 1200, None),
        ..XelaWsEmulatorConfig::texts(vec![], Duration::ZERO)
    })
    .unwrap();
    let rig = write(dir.path(), &two_patches_reading(&server.url(), ""));
    let (code, stderr, file) = collect(&rig, &dir.path().join("out"));
    assert_eq!(code, Some(0), "{stderr}");
    let info = SessionInfo::read(&file, ReadOptions::default()).unwrap();
    let channel = info.channels.iter().find(|c| c.topic == "/tactile/raw").unwrap();
    let layout = TaxelLayout::from_channel_metadata(&channel.metadata).unwrap().unwrap();
    let read = |s: &str| slidetrack_core::FingerReading::taxel(s, 0);
    assert_eq!(
        [&layout.fingers.thumb, &layout.fingers.index, &layout.fingers.middle],
        [&read("left"), &read("right"), &read("right")]
    );
}

#[test]
fn calibrated_null_records_no_forces() {
    let dir = tempdir();
    let messages = replay("v177_list_uspa44_x2.json", 700, Some(&Value::Null));
    let server = XelaWsEmulator::start(XelaWsEmulatorConfig {
        messages,
        ..XelaWsEmulatorConfig::texts(vec![], Duration::ZERO)
    })
    .unwrap();
    let rig = write(dir.path(), &two_patches(&server.url()));
    let (code, stderr, file) = collect(&rig, &dir.path().join("out"));
    assert_eq!(code, Some(0), "{stderr}");
    let info = SessionInfo::read(&file, ReadOptions::default()).unwrap();
    let topics: Vec<&str> = info.channels.iter().map(|c| c.topic.as_str()).collect();
    assert!(topics.contains(&"/tactile/raw") && topics.contains(&"/tactile/device_time"), "{topics:?}");
    assert!(!topics.contains(&"/tactile/calibrated"), "{topics:?}");
}

#[test]
fn a_server_gone_for_good_ends_the_trial_with_a_release_and_a_readable_file() {
    let dir = tempdir();
    let rig = emulated_rig(dir.path(), "disconnect_after_s = 2.5\n");
    let text = std::fs::read_to_string(&rig).unwrap().replace(
        "kind = \"xela_ws\"\n",
        "kind = \"xela_ws\"\nreconnect = { initial_backoff_ms = 50, max_backoff_ms = 100, max_duration_ms = 600 }\n",
    );
    std::fs::write(&rig, text).unwrap();
    let started = std::time::Instant::now();
    let (code, stderr, file) = collect(&rig, &dir.path().join("out"));
    assert_eq!(code, Some(1), "{stderr}");
    assert!(started.elapsed() < Duration::from_secs(8), "{:?}", started.elapsed());
    assert!(stderr.contains("disconnected") && stderr.contains("ws://127.0.0.1:"), "{stderr}");
    assert!(stderr.contains("the hand was released") && stderr.contains("scans recorded so far"), "{stderr}");

    assert_ended_by_disconnect(&file, 150..=270);
}

#[test]
fn a_short_outage_is_bridged_by_reconnecting_and_counted_as_a_gap() {
    let dir = tempdir();
    let rig = emulated_rig(dir.path(), "disconnect_after_s = 1.0\ndown_for_s = 0.3\n");
    let (code, stderr, file) = collect(&rig, &dir.path().join("out"));
    assert_eq!(code, Some(0), "{stderr}");
    let info = SessionInfo::read(&file, ReadOptions::default()).unwrap();
    assert_eq!(info.metadata["slidetrack.outcome"]["completed"], "true");
    let raw = read_channel::<TactileRaw>(&file, ReadOptions::default()).unwrap();
    let jumps: Vec<u64> =
        raw.windows(2).map(|w| w[1].1.sequence - w[0].1.sequence).filter(|&d| d != 1).collect();
    assert_eq!(jumps.len(), 1, "{jumps:?}");
    // Lost: the 0.3 s outage and the backoff wait after it (attempts at
    // 0, 0.1, 0.3, 0.7 s): 30 to 70 scans at 100 Hz.
    assert!((25..=110).contains(&jumps[0]), "scans lost: {jumps:?}");
    assert_eq!(last_counters(&file).gaps, 1);
}

#[test]
fn a_wrong_model_is_one_line_naming_the_setting() {
    let dir = tempdir();
    let rig = emulated_rig(dir.path(), "wrong_model = \"uSCu\"\n");
    let (code, stderr, file) = collect(&rig, &dir.path().join("out"));
    assert_eq!(code, Some(1), "{stderr}");
    let line = stderr.lines().find(|l| l.contains("uSCu")).unwrap_or_else(|| panic!("{stderr}"));
    assert!(
        line.contains("hw.tactile.sensors[2].model = uSPa44 but xela_server sends uSCu for sensor 3"),
        "{stderr}"
    );
    assert_eq!(stderr.matches("uSCu").count(), 1, "one message: {stderr}");
    // Nothing but the layout was recorded, and the file is readable.
    let info = SessionInfo::read(&file, ReadOptions::default()).unwrap();
    assert_eq!(info.metadata["slidetrack.outcome"]["completed"], "false");
}

#[test]
fn an_unreachable_server_or_a_bad_url_is_one_line() {
    let dir = tempdir();
    // A port nobody listens on: bound, then released.
    let port = std::net::TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port();
    let out = dir.path().join("out");
    let out = out.to_str().unwrap();
    for (url, wanted) in [
        (format!("ws://127.0.0.1:{port}"), "is xela_server running"),
        ("wss://127.0.0.1:5000".to_string(), "wss:// needs TLS"),
    ] {
        let text = two_patches(&url).replace(
            "kind = \"xela_ws\"\n",
            "kind = \"xela_ws\"\nreconnect = { initial_backoff_ms = 20, max_backoff_ms = 50, max_duration_ms = 300 }\n",
        );
        let rig = write(dir.path(), &text);
        let e = common::fails(&["collect", "--rig", "hw", "--config", &rig, "--duration", "1", "--out", out]);
        assert!(e.contains(&url) && e.contains(wanted), "{e}");
    }
}
