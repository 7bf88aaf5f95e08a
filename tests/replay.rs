//! The replay rig end to end: a session recorded by `track` and played back
//! by `track --rig replay` gives the same estimates, message for message,
//! and the same protocol, commands, hand states and marker track; `replay`
//! writes the grasp detector's `/estimate/slip` on every zeroed scan; bad
//! requests fail with one line.
#![expect(clippy::unwrap_used, reason = "test code: a failed unwrap is a failed test")]

mod common;

use std::collections::BTreeMap;
use std::path::Path;

use common::{collect, fails, ok, tempdir, trained};
use slidetrack_estimators::slip::GraspDetectorConfig;
use slidetrack_session::{
    ChannelMessage, GraspStateName, MessageReader, ReadOptions, SESSION_METADATA, SessionInfo, SlipEstimate,
    TactileZeroed, read_channel,
};

/// Every message of `topic` in `path`: `(log time, publish time, sequence, payload)`.
fn messages(path: &Path, topic: &str) -> Vec<(u64, u64, u32, Vec<u8>)> {
    MessageReader::open(path, &[topic], ReadOptions::default())
        .unwrap()
        .map(|m| {
            let m = m.unwrap();
            (m.log_time.0, m.publish_time.0, m.sequence, m.data)
        })
        .collect()
}

#[test]
fn a_replay_gives_the_estimates_of_the_live_run_message_for_message() {
    let dir = tempdir();
    let (_, model) = trained(dir.path());
    let (m, live, replayed) =
        (model.to_str().unwrap(), dir.path().join("live.mcap"), dir.path().join("replayed.mcap"));
    ok(&["-q", "track", "--model", m, "--duration", "8", "--seed", "5", "--out", live.to_str().unwrap()]);
    let args = ["-q", "track", "--rig", "replay", "--model", m, "--session", live.to_str().unwrap()];
    ok(&[&args[..], &["--out", replayed.to_str().unwrap()]].concat());

    for topic in [
        "/estimate/dekf",
        "/tactile/derivative",
        "/estimate/aruco",
        "/estimate/slip",
        "/hand/state",
        "/tactile/raw",
        "/tactile/tare",
        "/tactile/zeroed",
        "/control/grasp",
        "/hand/command",
        "/protocol/events",
        "/camera/image",
        "/camera/calibration",
        "/aruco/detections",
        "/sim/truth",
    ] {
        let (a, b) = (messages(&live, topic), messages(&replayed, topic));
        assert!(!a.is_empty(), "{topic}: nothing recorded live");
        assert_eq!(a.len(), b.len(), "{topic}: {} messages live, {} replayed", a.len(), b.len());
        if let Some(k) = a.iter().zip(&b).position(|(x, y)| x != y) {
            panic!(
                "{topic}: message {k} differs:\n  live   {:?}\n  replay {:?}",
                (a[k].0, String::from_utf8_lossy(&a[k].3)),
                (b[k].0, String::from_utf8_lossy(&b[k].3))
            );
        }
    }
    let meta: BTreeMap<String, String> =
        SessionInfo::read(&replayed, ReadOptions::default()).unwrap().metadata[SESSION_METADATA].clone();
    assert_eq!(meta["rig"], "replay");
    assert_eq!(meta["replay_of"], live.display().to_string());
}

#[test]
fn bad_replay_requests_fail_with_one_line() {
    let dir = tempdir();
    let (sessions, model) = trained(dir.path());
    let (m, s) = (model.to_str().unwrap(), sessions[0].to_str().unwrap());
    let e = fails(&["track", "--rig", "replay", "--model", m]);
    assert!(e.contains("--session"), "{e}");
    let e = fails(&["track", "--rig", "replay", "--model", m, "--session", s, "--out", s]);
    assert!(e.contains("must differ"), "{e}");
    let missing = dir.path().join("missing.mcap");
    let e = fails(&["track", "--rig", "replay", "--model", m, "--session", missing.to_str().unwrap()]);
    assert!(e.contains("missing.mcap"), "{e}");
    // A session recorded without the camera has no frames to track or render at.
    let e = fails(&["track", "--rig", "replay", "--model", m, "--session", s, "--vision", "roft"]);
    assert!(e.contains("renders the in-hand scene") && e.contains(s), "{e}");
    let e = fails(&["collect", "--rig", "replay", "--out", dir.path().to_str().unwrap()]);
    assert!(e.contains("track --rig replay"), "{e}");
}

// Catches: `replay` (without a model) not writing `/estimate/slip`, writing
// it on some scans only or at other times, a load other than the sum of the
// replayed scans' z, a score stuck at 0, and channel metadata without the
// detector's settings or the score's unit.
#[test]
fn replay_writes_the_grasp_detector_on_every_zeroed_scan_of_a_simulated_session() {
    let dir = tempdir();
    let session = collect(dir.path(), "box", 7, 6.0, &["--no-camera"]);
    let out = dir.path().join("slip.mcap");
    let printed = ok(&["-q", "replay", session.to_str().unwrap(), "--out", out.to_str().unwrap()]);
    assert!(printed.contains("grasp-detector scans"), "{printed}");
    let zeroed = read_channel::<TactileZeroed>(&out, ReadOptions::default()).unwrap();
    let slip = read_channel::<SlipEstimate>(&out, ReadOptions::default()).unwrap();
    assert!(zeroed.len() > 500, "{}", zeroed.len());
    assert_eq!(zeroed.len(), slip.len());
    for ((tz, z), (ts, e)) in zeroed.iter().zip(&slip) {
        assert_eq!(tz, ts);
        let load: f64 = z.sensors.iter().flat_map(|s| &s.taxels).map(|t| t.z).sum();
        assert!((e.load - load).abs() <= 1e-9 * load.abs().max(1.0), "{tz}: {} vs {load}", e.load);
    }
    assert!(slip.iter().any(|(_, e)| e.slip_score > 10.0), "the shear moves while the object slides");
    let info = SessionInfo::read(&out, ReadOptions::default()).unwrap();
    let meta = &info.channel(SlipEstimate::TOPIC).unwrap().metadata;
    let cfg: GraspDetectorConfig = serde_json::from_str(&meta["detector"]).unwrap();
    // The simulated rig's contact level, the defaults otherwise.
    assert_eq!(cfg, GraspDetectorConfig { contact_load_counts: 1000.0, ..GraspDetectorConfig::default() });
    assert_eq!(meta["slip_score_unit"], "counts/s");
    // The simulated grasp is held, and the protocol's release reads as a
    // release, not a drop.
    let states: Vec<GraspStateName> = slip.iter().map(|(_, e)| e.state).collect();
    assert!(states.iter().filter(|s| **s == GraspStateName::Holding).count() > 400, "{states:?}");
    assert!(!states.contains(&GraspStateName::Dropped), "the hand let go on purpose");
}
