//! The live view end to end: an independent Foxglove WebSocket client
//! (tests/python/live_client.py) during `track --live` and `play`, a viewer
//! that never reads during `collect --live`, and the errors of an address
//! that cannot serve.

mod common;

use std::io::{BufRead, BufReader};
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::process::{Child, Stdio};
use std::time::Duration;

use common::{SHORT_PROTOCOL, fails, python, slidetrack, tempdir, trained};
use slidetrack_core::TimeNs;
use slidetrack_live::StalledViewer;
use slidetrack_session::{MessageReader, ReadOptions};

/// Starts `slidetrack ARGS` and returns it with the address its live view
/// printed on stderr (`... on ws://ADDR ...`); the rest of stderr is drained.
fn spawn_live(args: &[&str]) -> (Child, SocketAddr) {
    let mut child =
        slidetrack().args(args).stderr(Stdio::piped()).stdout(Stdio::null()).spawn().expect("spawn");
    let mut lines = BufReader::new(child.stderr.take().expect("stderr")).lines();
    let addr = loop {
        let line = lines.next().expect("slidetrack printed its address").expect("stderr line");
        if let Some(rest) = line.split("ws://").nth(1) {
            break rest
                .split_whitespace()
                .next()
                .expect("address")
                .trim_end_matches(',')
                .parse()
                .expect("ADDR");
        }
    };
    std::thread::Builder::new()
        .name("slidetrack-stderr".into())
        .spawn(move || lines.map_while(Result::ok).for_each(|l| eprintln!("slidetrack: {l}")))
        .expect("stderr thread");
    (child, addr)
}

/// Runs the Python client against `addr` until the server closes; checks
/// against `session` when given. Returns its summary and its record.
fn run_client(
    addr: SocketAddr,
    dir: &Path,
    session: Option<&Path>,
) -> (std::process::Output, serde_json::Value) {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/python/live_client.py");
    let out = dir.join("client.json");
    let mut cmd = std::process::Command::new(python());
    cmd.arg(script).arg(format!("ws://{addr}")).arg(&out).args(["--idle", "3"]);
    if let Some(s) = session {
        cmd.arg("--session").arg(s);
    }
    let output = cmd.output().expect("python runs");
    let record = std::fs::read_to_string(&out)
        .map_or(serde_json::Value::Null, |s| serde_json::from_str(&s).expect("client record is JSON"));
    (output, record)
}

fn short_protocol(dir: &Path) -> PathBuf {
    let config = dir.join("rig.toml");
    std::fs::write(&config, SHORT_PROTOCOL).expect("write rig.toml");
    config
}

fn s(p: &Path) -> &str {
    p.to_str().expect("utf-8 path")
}

#[test]
fn a_viewer_during_track_gets_every_channel_and_the_recorded_messages() {
    let dir = tempdir();
    let (_, model) = trained(dir.path());
    let (config, out) = (short_protocol(dir.path()), dir.path().join("live.mcap"));
    let (mut child, addr) = spawn_live(&[
        "-q",
        "track",
        "--rig",
        "sim",
        "--model",
        s(&model),
        "--duration",
        "6",
        "--config",
        s(&config),
        "--out",
        s(&out),
        "--live",
        "127.0.0.1:0",
        "--live-image-hz",
        "0",
        "--live-wait",
        "60",
    ]);
    // The trial starts once the client has connected: as fast as possible, the simulated trial
    // is over in about a second, before a Python client started on a loaded machine connects
    // (the CI of stop 35). The client checks against the file once the server closes.
    let (client, _) = run_client(addr, dir.path(), Some(&out));
    assert!(child.wait().expect("track exits").success());
    let stdout = String::from_utf8_lossy(&client.stdout);
    assert!(client.status.success(), "client: {stdout}\n{}", String::from_utf8_lossy(&client.stderr));
    let summary: serde_json::Value = serde_json::from_str(&stdout).expect("summary");
    let received = &summary["received_per_topic"];
    for topic in
        ["/tactile/raw", "/estimate/dekf", "/camera/image", "/camera/calibration", "/protocol/events"]
    {
        assert!(received[topic].as_u64().unwrap_or(0) > 0, "{topic}: {summary}");
    }
    assert!(received["/tactile/raw"].as_u64().expect("raw") > 100, "{summary}");
}

/// Every message of a session, but the recorder's own statistics.
fn messages(path: &Path) -> Vec<(String, TimeNs, Vec<u8>)> {
    MessageReader::open(path, &[], ReadOptions::default())
        .expect("session")
        .map(|m| m.expect("message"))
        .filter(|m| m.channel.topic != "/recorder/stats")
        .map(|m| (m.channel.topic.clone(), m.log_time, m.data))
        .collect()
}

#[test]
fn a_viewer_that_never_reads_changes_nothing_in_the_session() {
    let dir = tempdir();
    let config = short_protocol(dir.path());
    let (with, without) = (dir.path().join("with"), dir.path().join("without"));
    // Two trials: the viewer subscribes during the first, the second runs entirely with it stalled.
    let args =
        ["-q", "collect", "--seed", "3", "--trials", "2", "--duration", "2", "--config", s(&config), "--out"];
    let (mut child, addr) =
        spawn_live(&[&args[..], &[s(&with), "--live", "127.0.0.1:0", "--live-image-hz", "0"]].concat());
    let viewer = StalledViewer::subscribe_all(addr, 8, Duration::from_secs(20)).expect("viewer subscribes");
    assert!(viewer.subscribed().len() >= 8, "{:?}", viewer.subscribed());
    assert!(child.wait().expect("collect exits").success(), "collect --live with a stalled viewer");
    drop(viewer);
    common::ok(&[&args[..], &[s(&without)]].concat());
    for name in ["box-s3-t000.mcap", "box-s3-t001.mcap"] {
        let (a, b) = (messages(&with.join(name)), messages(&without.join(name)));
        assert!(a.len() > 1000, "{} messages", a.len());
        assert_eq!(a.len(), b.len(), "{name}");
        for (x, y) in a.iter().zip(&b) {
            assert_eq!((&x.0, x.1), (&y.0, y.1));
            assert!(x.2 == y.2, "{name}: {} at {:?} differs with a stalled viewer", x.0, x.1);
        }
    }
}

#[test]
fn play_delivers_a_session_at_its_recorded_timing() {
    let dir = tempdir();
    let config = short_protocol(dir.path());
    let session = common::collect(dir.path(), "box", 5, 1.0, &["--no-camera", "--config", s(&config)]);
    let (mut child, addr) = spawn_live(&["play", s(&session), "--live", "127.0.0.1:0", "--rate", "1"]);
    let (client, record) = run_client(addr, dir.path(), Some(&session));
    assert!(child.wait().expect("play exits").success());
    let stdout = String::from_utf8_lossy(&client.stdout);
    assert!(client.status.success(), "client: {stdout}\n{}", String::from_utf8_lossy(&client.stderr));
    let msgs = record["messages"].as_array().expect("messages");
    let total = messages(&session).len();
    assert!(msgs.len() + 2 >= total, "received {} of {total} messages", msgs.len());
    // Lateness of each message behind the recorded timing, from the earliest one (ms).
    let offsets: Vec<f64> = msgs
        .iter()
        .map(|m| m["received_s"].as_f64().expect("t") * 1e3 - m["log_time"].as_f64().expect("log") / 1e6)
        .collect();
    let first = offsets.iter().copied().fold(f64::INFINITY, f64::min);
    let mut late: Vec<f64> = offsets.iter().map(|o| o - first).collect();
    late.sort_by(f64::total_cmp);
    let (median, p99) = (late[late.len() / 2], late[late.len() * 99 / 100]);
    // A few ms per message; both bounds leave room for a loaded CI machine (the median is
    // 3.0-3.2 ms with four busy loops per core). Sent all at once, the median would be half
    // the session; played at half the rate, a quarter of it.
    assert!(median < 5.0 && p99 < 25.0, "lateness median {median:.2} ms, p99 {p99:.2} ms");
}

#[test]
fn an_address_that_cannot_serve_is_one_line_before_the_trial() {
    let dir = tempdir();
    let taken = std::net::TcpListener::bind("127.0.0.1:0").expect("bind");
    let port = taken.local_addr().expect("addr").port();
    let out = dir.path().join("out");
    let busy = format!("127.0.0.1:{port}");
    for (addr, says) in
        [(busy.as_str(), "in use"), ("192.0.2.1:8765", "cannot serve"), ("nowhere", "HOST:PORT")]
    {
        let e = fails(&["collect", "--duration", "1", "--out", s(&out), "--live", addr]);
        assert!(e.contains(says), "{addr}: {e}");
        assert!(!out.join("box-s1-t000.mcap").exists(), "{addr}: no trial ran");
    }
    // After the lines saying where it serves and that it waits: one error line.
    let waited = common::run(&[
        "collect",
        "--duration",
        "1",
        "--out",
        s(&out),
        "--live",
        "127.0.0.1:0",
        "--live-wait",
        "0.2",
    ]);
    let e = String::from_utf8_lossy(&waited.stderr);
    assert_eq!(waited.status.code(), Some(1), "{e}");
    let last = e.lines().last().unwrap_or_default();
    assert!(last.starts_with("error: no viewer connected to ws://") && last.contains("--live-wait"), "{e}");
    assert!(!out.join("box-s1-t000.mcap").exists(), "--live-wait: no trial ran");
    let e = fails(&["play", s(&dir.path().join("missing.mcap")), "--live", "127.0.0.1:0"]);
    assert!(e.contains("missing.mcap"), "{e}");
}

/// `node` and the project's node_modules (`target/node/node_modules`, or
/// `SLIDETRACK_NODE_MODULES`) holding the official `@foxglove/ws-protocol`
/// client, made by `scripts/setup.sh --test`; `None` (the test then skips,
/// saying why) when either is missing.
fn node_with_ws_protocol() -> Option<(PathBuf, PathBuf)> {
    let modules = std::env::var_os("SLIDETRACK_NODE_MODULES").map_or_else(
        || Path::new(env!("CARGO_MANIFEST_DIR")).join("target/node/node_modules"),
        PathBuf::from,
    );
    let node = std::env::var_os("PATH")
        .and_then(|paths| std::env::split_paths(&paths).map(|p| p.join("node")).find(|p| p.is_file()));
    match node {
        Some(node) if modules.join("@foxglove/ws-protocol/package.json").is_file() => Some((node, modules)),
        Some(_) => {
            eprintln!(
                "skipped: no @foxglove/ws-protocol in {} (run scripts/setup.sh --test)",
                modules.display()
            );
            None
        }
        None => {
            eprintln!("skipped: no `node` on PATH (run scripts/setup.sh --test)");
            None
        }
    }
}

#[test]
fn the_official_open_protocol_client_gets_the_recorded_bytes() {
    let Some((node, modules)) = node_with_ws_protocol() else { return };
    let dir = tempdir();
    let out = dir.path().join("sessions");
    // Several trials as fast as the simulator goes (a real-time trial on a
    // loaded machine may abort at once on stale data): the client connects
    // during one of them and gets what the live view sends it.
    let args = ["-q", "collect", "--seed", "4", "--trials", "3", "--duration", "6"];
    let (mut child, addr) = spawn_live(
        &[&args[..], &["--out", s(&out), "--live", "127.0.0.1:0", "--live-image-hz", "0"]].concat(),
    );
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/node/live_client_open.js");
    let record_path = dir.path().join("open_client.json");
    let client = std::process::Command::new(node)
        .env("NODE_PATH", &modules)
        .arg(script)
        .arg(format!("ws://{addr}"))
        .arg(&record_path)
        .args(["3", "30"])
        .output()
        .expect("node runs");
    assert!(child.wait().expect("collect exits").success());
    assert!(client.status.success(), "client: {}", String::from_utf8_lossy(&client.stderr));
    let text = std::fs::read_to_string(&record_path).expect("client record");
    let record: serde_json::Value = serde_json::from_str(&text).expect("client record is JSON");
    assert_eq!(record["subprotocol"], "foxglove.websocket.v1", "{}", record["errors"]);
    let in_file: std::collections::HashSet<_> = std::fs::read_dir(&out)
        .expect("sessions")
        .flat_map(|f| {
            MessageReader::open(f.expect("entry").path(), &[], ReadOptions::default()).expect("session")
        })
        .map(|m| m.expect("message"))
        .map(|m| (m.channel.topic.clone(), m.log_time, m.data))
        .collect();
    let mut per_topic = std::collections::BTreeMap::<String, usize>::new();
    for m in record["messages"].as_array().expect("messages") {
        let topic = m["topic"].as_str().expect("topic").to_string();
        let log_time = TimeNs(m["log_time"].as_str().expect("log time").parse().expect("u64"));
        let data = from_hex(m["data"].as_str().expect("data"));
        assert!(
            in_file.contains(&(topic.clone(), log_time, data)),
            "{topic} at {log_time:?}: not the file's bytes"
        );
        *per_topic.entry(topic).or_default() += 1;
    }
    assert!(per_topic.get("/tactile/raw").copied().unwrap_or(0) > 20, "{per_topic:?}");
}

/// The bytes of a hex string (the Node client's record).
fn from_hex(hex: &str) -> Vec<u8> {
    (0..hex.len()).step_by(2).map(|i| u8::from_str_radix(&hex[i..i + 2], 16).expect("hex")).collect()
}
