//! Helpers shared by the end-to-end tests: run the CLI as a process.

// Each test binary compiles this module and uses its own part of it, so
// `dead_code` fires in some binaries and not in others: an `#[expect]` would
// be unfulfilled in the binaries that use every helper. Hence the one
// `allow` of the workspace.
#![allow(dead_code, reason = "each test binary uses its own part of these helpers")]

pub mod cyclone;
pub mod rosbags;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// The `slidetrack` binary under test.
pub fn slidetrack() -> Command {
    Command::new(env!("CARGO_BIN_EXE_slidetrack"))
}

/// Runs `slidetrack ARGS` and returns its output.
pub fn run(args: &[&str]) -> Output {
    slidetrack().args(args).output().expect("slidetrack runs")
}

/// Runs `slidetrack ARGS`, panicking with its stderr unless it succeeds.
pub fn ok(args: &[&str]) -> String {
    let out = run(args);
    assert!(out.status.success(), "slidetrack {args:?} failed:\n{}", String::from_utf8_lossy(&out.stderr));
    String::from_utf8(out.stdout).expect("utf-8 output")
}

/// Runs `slidetrack ARGS` expecting a clean failure: exit code 1 and a single
/// `error: ...` line on stderr, no panic. Returns that line.
pub fn fails(args: &[&str]) -> String {
    let out = run(args);
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(1), "slidetrack {args:?}: expected exit 1, stderr:\n{stderr}");
    assert!(!stderr.contains("panicked"), "slidetrack {args:?} panicked:\n{stderr}");
    let lines: Vec<_> = stderr.lines().filter(|l| !l.trim().is_empty()).collect();
    assert_eq!(lines.len(), 1, "slidetrack {args:?}: expected one line on stderr, got:\n{stderr}");
    assert!(lines[0].starts_with("error: "), "{stderr}");
    lines[0].to_string()
}

/// A fresh temporary directory.
pub fn tempdir() -> tempfile::TempDir {
    tempfile::tempdir().expect("temporary directory")
}

/// Collects one simulated trial into `dir` and returns its path.
pub fn collect(dir: &Path, object: &str, seed: u64, duration_s: f64, extra: &[&str]) -> PathBuf {
    let d = duration_s.to_string();
    let s = seed.to_string();
    let out = dir.to_str().expect("utf-8 path");
    let mut args = vec!["-q", "collect", "--object", object, "--duration", &d, "--seed", &s, "--out", out];
    args.extend_from_slice(extra);
    ok(&args);
    dir.join(format!("{object}-s{seed}-t000.mcap"))
}

/// The project's Python (`target/pyenv`, made by `scripts/setup.sh --test`,
/// or `SLIDETRACK_PYTHON`), which has the official `mcap` package and NumPy.
/// Never the system's `python3`: a test must not pass only because a
/// package happens to be installed by hand.
pub fn python() -> PathBuf {
    let python = project_python_path();
    assert!(
        python.exists(),
        "{} does not exist: run `scripts/setup.sh --test` (or `scripts/test`), which makes the \
         project's Python environment",
        python.display()
    );
    python
}

/// Where the project's Python is: `SLIDETRACK_PYTHON`, else target/pyenv.
fn project_python_path() -> PathBuf {
    std::env::var_os("SLIDETRACK_PYTHON")
        .map_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("target/pyenv/bin/python"), PathBuf::from)
}

/// The project's Python when it exists and runs `import {import}`; `None`
/// otherwise, after saying on stderr why the test skips (`package` names
/// what is missing).
pub fn python_importing(import: &str, package: &str) -> Option<PathBuf> {
    let python = project_python_path();
    if !python.exists() {
        eprintln!("skipped: no {} (run scripts/setup.sh --test)", python.display());
        return None;
    }
    let imported = Command::new(&python).args(["-c", &format!("import {import}")]).output();
    if !imported.is_ok_and(|o| o.status.success()) {
        eprintln!("skipped: {} cannot import {package} (run scripts/setup.sh --test)", python.display());
        return None;
    }
    Some(python)
}

/// Three short simulated sessions without camera, and a tiny model trained on
/// the first two against the simulator's truth.
pub fn trained(dir: &Path) -> (Vec<PathBuf>, PathBuf) {
    let sessions: Vec<PathBuf> =
        (0..3u64).map(|s| collect(dir, "box", 20 + s, 12.0, &["--no-camera"])).collect();
    let model = dir.join("box.safetensors");
    let (a, b) = (sessions[0].to_str().expect("utf-8 path"), sessions[1].to_str().expect("utf-8 path"));
    ok(&[
        "-q",
        "train",
        a,
        b,
        "--truth",
        "sim",
        "--channels",
        "xy",
        "--schedule",
        "2:1,8:1",
        "--threads",
        "1",
        "--out",
        model.to_str().expect("utf-8 path"),
    ]);
    (sessions, model)
}

/// A `[sim.tactile.patch]` table: a 4x4 patch per fingertip on the simulated rig.
pub const SIM_PATCH_4X4: &str = "
[sim.tactile.patch]
rows = 4
cols = 4
pitch_mm = 4.7
contact_sigma_mm = 6.0
";

/// A hardware rig (`[hw]`, named `emulated-serial`) whose fingertips are
/// the simulated rig's patches read through the serial emulator on a
/// pseudo-terminal as three uSkin-style modules (the default sensors), with
/// the simulated hand; the camera tables are the caller's.
pub const SERIAL_EMULATED: &str = "
[hw]
name = \"emulated-serial\"
[hw.tactile]
kind = \"serial\"
port = \"emulated\"
fingers = { thumb = { sensor = \"thumb\" }, index = { sensor = \"index\" }, middle = { sensor = \"middle\" } }
[hw.hand]
kind = \"sim\"
";

/// A `[protocol]` table with the phases before and after the cycles cut
/// short, so that real-time trials on emulated devices take seconds.
pub const SHORT_PROTOCOL: &str = "
[protocol]
zero_duration_s = 0.5
ramp_duration_s = 1.0
settle_duration_s = 1.5
release_duration_s = 0.3
";

/// Checks the session a device loss ended: finished (not truncated), the
/// outcome incomplete and aborted as `disconnected`, `scans` tactile scans,
/// `aborted` the last protocol event. Returns the session's facts.
pub fn assert_ended_by_disconnect(
    file: &Path,
    scans: std::ops::RangeInclusive<usize>,
) -> slidetrack_session::SessionInfo {
    use slidetrack_session::{ReadOptions, SessionInfo, TactileRaw, read_channel};
    let info = SessionInfo::read(file, ReadOptions::default()).expect("a finished, readable session");
    assert!(!info.truncated);
    let outcome = &info.metadata["slidetrack.outcome"];
    assert_eq!(outcome["completed"], "false");
    assert!(outcome["abort_reason"].contains("disconnected"), "{outcome:?}");
    let raw = read_channel::<TactileRaw>(file, ReadOptions::default()).expect("tactile scans");
    assert!(scans.contains(&raw.len()), "{} scans, expected {scans:?}", raw.len());
    let events = ok(&["export", file.to_str().expect("utf-8 path"), "--channel", "/protocol/events"]);
    assert!(events.lines().last().expect("events").contains("aborted"), "{events}");
    info
}

/// Runs the NumPy implementation of docs/model-format.md on `model` and the
/// `replay` output `out`, and checks it reproduces the replay's `steps`
/// estimates to 1e-4; returns its JSON.
pub fn check_against_the_reference(model: &str, out: &Path, steps: u64) -> serde_json::Value {
    let py = Command::new(python())
        .arg(concat!(env!("CARGO_MANIFEST_DIR"), "/tests/python/dekf_reference.py"))
        .args([model, out.to_str().expect("utf-8 path")])
        .output()
        .expect("python runs");
    let stderr = String::from_utf8_lossy(&py.stderr);
    assert!(py.status.success(), "reference failed (scripts/test installs mcap and numpy):\n{stderr}");
    let r: serde_json::Value = serde_json::from_slice(&py.stdout).expect("JSON from the reference");
    assert_eq!(r["steps"].as_u64(), Some(steps));
    for key in ["position", "velocity", "covariance"] {
        let d = r["max_relative_difference"][key].as_f64().expect("a difference");
        assert!(d < 1e-4, "{key}: relative difference {d}");
    }
    r
}

/// A rig with its camera off the default placement and a marker fixed to
/// the hand as `calibrate hand`'s target (the hand-frame tests).
pub const HAND_TARGET_RIG: &str = r#"
[camera]
placement = { kind = "look_at", position_m = [0.28, 0.06, 0.14], look_at_m = [0.08, -0.01, 0.0], up_in_hand = [0.1, 0.0, 1.0] }

[hand_target]
dictionary = "DICT_6X6_250"
id = 11
marker_size_m = 0.05
hand_from_target = { translation_m = [0.1024, 0.0069, 0.0086], quaternion_xyzw = [0.351615, 0.452679, 0.671449, 0.469686] }
"#;
