//! `slidetrack record`: the devices recorded without the protocol, the hand
//! never opened, the file finished on every path out.

mod common;

use std::path::Path;

use common::{SIM_PATCH_4X4, fails, ok, run, tempdir};
use slidetrack_core::Phase;
use slidetrack_session::{
    HandState, ProtocolEvent, ReadOptions, SessionInfo, SimTruth, TactileRaw, read_channel,
};

fn write_rig(dir: &Path, text: &str) -> String {
    let path = dir.join("rig.toml");
    std::fs::write(&path, text).expect("rig written");
    path.to_str().expect("utf-8 path").to_string()
}

fn events(file: &Path) -> Vec<ProtocolEvent> {
    read_channel::<ProtocolEvent>(file, ReadOptions::default())
        .expect("events")
        .into_iter()
        .map(|e| e.1)
        .collect()
}

#[test]
fn the_simulated_rig_is_recorded_for_the_duration_without_the_protocols_channels() {
    let dir = tempdir();
    let rig = write_rig(dir.path(), SIM_PATCH_4X4);
    let file = dir.path().join("out/sim.mcap");
    let f = file.to_str().unwrap();
    let line = ok(&["-q", "record", "--rig", "sim", "--config", &rig, "--duration", "2", "--out", f]);
    assert!(line.contains("complete; 2.0 s, 200 scans"), "{line}");

    let info = SessionInfo::read(&file, ReadOptions::default()).unwrap();
    assert_eq!(info.metadata["slidetrack.outcome"]["completed"], "true");
    assert_eq!(info.metadata["slidetrack"]["recording"], "record");
    // The protocol's channels are not there: nothing tared, controlled or commanded.
    for topic in ["/tactile/tare", "/tactile/zeroed", "/control/grasp", "/hand/command"] {
        assert!(info.channel(topic).is_none(), "{topic} recorded");
    }
    let raw = read_channel::<TactileRaw>(&file, ReadOptions::default()).unwrap();
    assert_eq!(raw.len(), 200, "100 Hz for 2 s");
    assert!(raw.iter().all(|(_, r)| r.sensors.iter().map(|s| s.taxels.len()).sum::<usize>() == 48));
    // The hand is never commanded: its fingers stay where they rest.
    let hand = read_channel::<HandState>(&file, ReadOptions::default()).unwrap();
    assert_eq!(hand.len(), raw.len(), "a hand state with each scan");
    assert!(hand.iter().all(|(_, h)| h.finger_travel == [0.0; 3] && h.opening.is_none()));
    let truth = read_channel::<SimTruth>(&file, ReadOptions::default()).unwrap();
    assert!(
        truth.iter().all(|(_, t)| t.normal_force.into_array() == [0.0; 3]),
        "nothing squeezes the object"
    );
    let events = events(&file);
    assert_eq!(events.len(), 1, "{events:?}");
    assert_eq!(events[0].phase, Phase::Done);
}

/// The emulated serial sensors (real decoder, pseudo-terminal) unplugged
/// mid-recording; the configured CAN hand on an interface that does not exist
/// would fail to open, so the recording shows it was never opened.
#[test]
fn an_unplugged_sensor_ends_the_recording_with_a_readable_file_and_the_hand_is_never_opened() {
    let dir = tempdir();
    let rig = write_rig(
        dir.path(),
        &format!(
            "[hw]\nname = \"dry-run\"\n[hw.tactile]\nkind = \"serial\"\nport = \"emulated\"\n\
             [hw.tactile.emulator]\nunplug_after_s = 1.0\n[hw.camera]\nkind = \"none\"\n\
             [hw.hand]\nkind = \"can\"\ninterface = \"slidetrack-no-such-can\"\n{SIM_PATCH_4X4}"
        ),
    );
    let file = dir.path().join("unplugged.mcap");
    let f = file.to_str().unwrap();
    let out = run(&["-q", "record", "--config", &rig, "--duration", "5", "--out", f]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("disconnected") && stderr.contains("keeps the"), "{stderr}");
    assert!(!stderr.contains("slidetrack-no-such-can"), "the hand was opened: {stderr}");

    let info = SessionInfo::read(&file, ReadOptions::default()).expect("a finished, readable file");
    assert_eq!(info.metadata["slidetrack.outcome"]["completed"], "false");
    let raw = read_channel::<TactileRaw>(&file, ReadOptions::default()).unwrap();
    assert!((60..=120).contains(&raw.len()), "{} scans in about 1 s at 100 Hz", raw.len());
    let last = events(&file).pop().expect("an end event");
    assert_eq!(last.phase, Phase::Aborted);
    assert!(last.abort && last.message.contains("disconnected"), "{last:?}");
    assert!(info.channel("/tactile/decoder").is_some(), "the decoder's counters are kept");
}

#[test]
fn bad_arguments_are_one_line_errors() {
    let dir = tempdir();
    let f = dir.path().join("x.mcap");
    let f = f.to_str().unwrap();
    assert!(fails(&["record", "--rig", "sim", "--duration=-1", "--out", f]).contains("--duration"));
    assert!(fails(&["record", "--rig", "replay", "--out", f]).contains("record records live devices"));
    let e = fails(&["record", "--rig", "hw", "--duration", "1", "--out", f]);
    assert!(e.contains("[hw]"), "{e}");
    ok(&["-q", "record", "--rig", "sim", "--duration", "0.1", "--out", f]);
    assert!(fails(&["record", "--rig", "sim", "--duration", "0.1", "--out", f]).contains("--overwrite"));
}

/// The simulated 4x4 patches served by a local `xela_server` emulator that
/// sends a malformed message every 40 scans and goes away after `gone_s`.
fn xela_rig(dir: &Path, gone_s: Option<f64>) -> String {
    let gone = gone_s.map_or(String::new(), |s| format!("disconnect_after_s = {s}\n"));
    write_rig(
        dir,
        &format!(
            "[hw]\nname = \"xela-dry-run\"\n[hw.tactile]\nkind = \"xela_ws\"\nurl = \"emulated\"\n\
             reconnect = {{ initial_backoff_ms = 20, max_backoff_ms = 50, max_duration_ms = 300 }}\n\
             fingers = {{ thumb = {{ sensor = \"thumb\" }}, index = {{ sensor = \"index\" }}, middle = {{ sensor = \"middle\" }} }}\n\
             [hw.tactile.emulator]\nmalformed_every = 40\n{gone}\
             [hw.camera]\nkind = \"none\"\n[hw.hand]\nkind = \"can\"\ninterface = \"slidetrack-no-such-can\"\n\
             {SIM_PATCH_4X4}"
        ),
    )
}

#[test]
fn a_xela_server_is_recorded_with_every_taxel_and_malformed_messages_counted() {
    let dir = tempdir();
    let rig = xela_rig(dir.path(), None);
    let file = dir.path().join("xela.mcap");
    let f = file.to_str().unwrap();
    let line = ok(&["-q", "record", "--config", &rig, "--duration", "1.5", "--out", f]);
    assert!(line.contains("complete"), "{line}");
    assert!(line.contains("tactile decoder"), "the decoder's counters are reported: {line}");

    let info = SessionInfo::read(&file, ReadOptions::default()).unwrap();
    assert_eq!(info.metadata["slidetrack.outcome"]["completed"], "true");
    let raw = read_channel::<TactileRaw>(&file, ReadOptions::default()).unwrap();
    assert!(raw.len() > 100, "{} scans in 1.5 s at 100 Hz", raw.len());
    assert!(raw.iter().all(|(_, r)| r.sensors.iter().map(|s| s.taxels.len()).sum::<usize>() == 48));
    let decoder = read_channel::<slidetrack_session::TactileDecoder>(&file, ReadOptions::default()).unwrap();
    let last = decoder.last().expect("the decoder's counters").1;
    assert!(last.incomplete_scans >= 2, "malformed messages counted: {last:?}");
    assert!(info.channel("/tactile/device_time").is_some(), "the server's time is kept");
}

#[test]
fn a_xela_server_that_goes_away_ends_the_recording_with_a_readable_file() {
    let dir = tempdir();
    let rig = xela_rig(dir.path(), Some(0.8));
    let file = dir.path().join("gone.mcap");
    let f = file.to_str().unwrap();
    let out = run(&["-q", "record", "--config", &rig, "--duration", "10", "--out", f]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("disconnected") && stderr.contains("ws://127.0.0.1"), "{stderr}");
    let info = SessionInfo::read(&file, ReadOptions::default()).expect("a finished, readable file");
    assert_eq!(info.metadata["slidetrack.outcome"]["completed"], "false");
    let raw = read_channel::<TactileRaw>(&file, ReadOptions::default()).unwrap();
    assert!((40..=100).contains(&raw.len()), "{} scans in about 0.8 s", raw.len());
}

/// The simulated patches behind an SLCAN adapter emulated on a
/// pseudo-terminal, in the legacy CAN layout, unplugged after `unplug_s`.
#[test]
fn an_slcan_adapter_is_recorded_and_its_unplugging_leaves_a_readable_file() {
    let dir = tempdir();
    let rig = |unplug: &str| {
        write_rig(
            dir.path(),
            &format!(
                "[hw]\nname = \"slcan-dry-run\"\n[hw.tactile]\nkind = \"can\"\n\
                 slcan = {{ port = \"emulated\"{unplug} }}\n\
                 fingers = {{ thumb = {{ sensor = \"thumb\" }}, index = {{ sensor = \"index\" }}, middle = {{ sensor = \"middle\" }} }}\n\
                 [hw.camera]\nkind = \"none\"\n[hw.hand]\nkind = \"sim\"\n{SIM_PATCH_4X4}"
            ),
        )
    };
    let file = dir.path().join("slcan.mcap");
    let f = file.to_str().unwrap();
    let line = ok(&["-q", "record", "--config", &rig(""), "--duration", "1", "--out", f]);
    assert!(line.contains("complete"), "{line}");
    let raw = read_channel::<TactileRaw>(&file, ReadOptions::default()).unwrap();
    assert!(raw.len() > 60, "{} scans in 1 s at 100 Hz", raw.len());
    assert!(raw.iter().all(|(_, r)| r.sensors.iter().map(|s| s.taxels.len()).sum::<usize>() == 48));

    let gone = dir.path().join("unplugged.mcap");
    let g = gone.to_str().unwrap();
    let out =
        run(&["-q", "record", "--config", &rig(", unplug_after_s = 0.8"), "--duration", "5", "--out", g]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    let info = SessionInfo::read(&gone, ReadOptions::default()).expect("a finished, readable file");
    assert_eq!(info.metadata["slidetrack.outcome"]["completed"], "false");
    let raw = read_channel::<TactileRaw>(&gone, ReadOptions::default()).unwrap();
    assert!((30..=100).contains(&raw.len()), "{} scans in about 0.8 s", raw.len());
}
