//! `[hw.tactile] kind = "ros2"` end to end: an independent DDS
//! implementation, Eclipse Cyclone DDS through its Python binding
//! (tests/python/xela_ros2_publisher.py), publishes
//! `xela_server_ros2/msg/SensStream` on `/xServTopic` as XELA's ROS 2
//! server does, `slidetrack record` subscribes through RustDDS, and every
//! recorded taxel count, force and server time equals what Python
//! published for that message counter, with no message lost in between.
//!
//! The DDS setup is that of tests/ros2_live.rs: its own domain id, Cyclone
//! DDS on loopback by unicast (CYCLONEDDS_URI). Skipped, saying why, when
//! the project's Python cannot import `cyclonedds`.
#![cfg(all(feature = "devices", target_os = "linux"))]

mod common;

use std::collections::HashMap;
use std::path::Path;
use std::process::Child;

use common::cyclone::{lease_domain, python_with_cyclonedds, start_ready, stop_and_read};
use common::{run, tempdir};
use serde_json::Value;
use slidetrack_session::{ReadOptions, TactileCalibrated, TactileDeviceTime, TactileRaw, read_channel};

/// Stops the publisher; what it published, by message counter, then by sensor_pos.
fn published(child: Child) -> HashMap<u64, HashMap<u64, Value>> {
    stop_and_read(child)
        .into_iter()
        .map(|m| {
            let sensors = m["sensors"].as_array().expect("sensors");
            let n = sensors[0]["message"].as_u64().expect("message");
            (n, sensors.iter().map(|s| (s["sensor_pos"].as_u64().expect("pos"), s.clone())).collect())
        })
        .collect()
}

/// `slidetrack -q record` for 2 s with the rig `rig_path`, into `file`.
fn record(rig_path: &Path, file: &Path) -> std::process::Output {
    run(&[
        "-q",
        "record",
        "--config",
        rig_path.to_str().expect("utf-8 path"),
        "--duration",
        "2",
        "--out",
        file.to_str().expect("utf-8 path"),
    ])
}

/// sensor_pos 2 first, then 1 (the layout's order is the table's, not the
/// server's); sensor_pos 3, which the server also sends, is not taken.
fn rig(domain: u32) -> String {
    format!(
        "[hw]
name = \"xela-ros2\"
[hw.tactile]
kind = \"ros2\"
domain_id = {domain}
fingers = {{ thumb = {{ sensor = \"a\" }}, index = {{ sensor = \"b\" }}, middle = {{ sensor = \"b\", taxel = 5 }} }}
[[hw.tactile.sensors]]
name = \"a\"
sensor = 2
finger = \"thumb\"
model = \"uSPa44\"
rows = 4
cols = 4
[[hw.tactile.sensors]]
name = \"b\"
sensor = 1
finger = \"index\"
model = \"USPA44\"
rows = 4
cols = 4
[hw.hand]
kind = \"sim\"
[hw.camera]
kind = \"none\"
"
    )
}

fn f64s(v: &Value) -> Vec<f64> {
    v.as_array()
        .expect("array")
        .iter()
        .flat_map(|t| t.as_array().expect("xyz").iter().map(|x| x.as_f64().expect("number")))
        .collect()
}

#[test]
fn every_taxel_published_by_cyclone_dds_is_recorded() {
    let Some(python) = python_with_cyclonedds() else { return };
    let dir = tempdir();
    let (domain, _lease) = lease_domain();
    let rig_path = dir.path().join("rig.toml");
    std::fs::write(&rig_path, rig(domain)).expect("rig TOML");
    let file = dir.path().join("xela.mcap");
    let publisher = start_ready(&python, "xela_ros2_publisher.py", domain);
    let out = record(&rig_path, &file);
    let sent = published(publisher);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "record failed: {stderr}");

    let raw = read_channel::<TactileRaw>(&file, ReadOptions::default()).expect("a readable session");
    assert!(raw.len() >= 50, "{} scans in 2 s at 100 Hz", raw.len());
    eprintln!(
        "{} scans recorded, messages {} to {}",
        raw.len(),
        raw[0].1.sequence,
        raw[raw.len() - 1].1.sequence
    );
    let sequences: Vec<u64> = raw.iter().map(|(_, m)| m.sequence).collect();
    assert!(sequences.windows(2).all(|w| w[1] == w[0] + 1), "no message lost or repeated: {sequences:?}");
    for (_, m) in &raw {
        let sent = &sent[&m.sequence];
        let names: Vec<&str> = m.sensors.iter().map(|s| s.name.as_str()).collect();
        assert_eq!(names, ["a", "b"]);
        for (sensor, pos) in m.sensors.iter().zip([2, 1]) {
            let got: Vec<f64> = sensor.taxels.iter().flat_map(|t| t.to_array()).map(f64::from).collect();
            assert_eq!(got, f64s(&sent[&pos]["taxels"]), "message {} sensor_pos {pos}", m.sequence);
        }
    }
    let extremes = &raw[0].1.sensors[1].taxels[0].to_array();
    assert_eq!(extremes, &[0, 65535, 32768], "the full 16-bit range, unsigned");

    let forces = read_channel::<TactileCalibrated>(&file, ReadOptions::default()).expect("forces");
    assert_eq!(forces.len(), raw.len(), "every sensor taken carries forces");
    for (_, m) in &forces {
        for (sensor, pos) in m.sensors.iter().zip([2, 1]) {
            let got: Vec<f64> = sensor.taxels.iter().flat_map(|t| t.to_array()).collect();
            assert_eq!(got, f64s(&sent[&m.sequence][&pos]["forces"]), "forces of {}", m.sequence);
        }
    }
    let times = read_channel::<TactileDeviceTime>(&file, ReadOptions::default()).expect("device times");
    for (_, t) in &times {
        assert_eq!(t.device_time_s, sent[&t.sequence][&2]["time"].as_f64().unwrap());
    }
    assert_eq!(times.len(), raw.len());
}

#[test]
fn a_sensor_the_server_does_not_send_is_named_in_one_line() {
    let Some(python) = python_with_cyclonedds() else { return };
    let dir = tempdir();
    let (domain, _lease) = lease_domain();
    let rig_path = dir.path().join("rig.toml");
    std::fs::write(&rig_path, rig(domain).replace("sensor = 1\n", "sensor = 9\n")).expect("rig TOML");
    let file = dir.path().join("xela.mcap");
    let publisher = start_ready(&python, "xela_ros2_publisher.py", domain);
    let out = record(&rig_path, &file);
    drop(published(publisher));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && !stderr.contains("panicked"), "{stderr}");
    assert!(
        stderr.contains("hw.tactile.sensors[1].sensor = 9 but xela_server_ros2 sends sensor_pos [1, 2, 3]"),
        "{stderr}"
    );
}

/// Needs no Python: with nobody publishing, the first read times out and
/// the recording stops with one line naming the topic and the wait.
#[test]
fn no_publisher_is_a_startup_timeout_naming_the_topic() {
    let dir = tempdir();
    let rig_path = dir.path().join("rig.toml");
    let (domain, _lease) = lease_domain();
    let text = rig(domain).replace("kind = \"ros2\"\n", "kind = \"ros2\"\nstartup_timeout_ms = 1500\n");
    std::fs::write(&rig_path, text).expect("rig TOML");
    let file = dir.path().join("xela.mcap");
    let out = record(&rig_path, &file);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && !stderr.contains("panicked"), "{stderr}");
    assert!(
        stderr.contains("ROS 2 topic /xServTopic") && stderr.contains("no SensStream within 1500 ms"),
        "{stderr}"
    );
}
