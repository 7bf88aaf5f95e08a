//! The dEKF end to end through the CLI: train, replay (checked against an
//! independent implementation of docs/model-format.md), eval, bad input.
#![expect(clippy::unwrap_used, reason = "test code: a failed unwrap is a failed test")]

mod common;

use std::path::Path;
use std::process::Command;

use common::{collect, fails, ok, python, tempdir, trained};

/// Runs the NumPy implementation of docs/model-format.md on `model` and the
/// `replay` output `out`, and checks it reproduces the replay's `steps`
/// estimates to 1e-4; returns its JSON.
fn check_against_the_reference(model: &str, out: &Path, steps: u64) -> serde_json::Value {
    let py = Command::new(python())
        .arg(concat!(env!("CARGO_MANIFEST_DIR"), "/tests/python/dekf_reference.py"))
        .args([model, out.to_str().unwrap()])
        .output()
        .expect("python runs");
    let stderr = String::from_utf8_lossy(&py.stderr);
    assert!(py.status.success(), "reference failed (scripts/test installs mcap and numpy):\n{stderr}");
    let r: serde_json::Value = serde_json::from_slice(&py.stdout).unwrap();
    assert_eq!(r["steps"].as_u64(), Some(steps));
    for key in ["position", "velocity", "covariance"] {
        let d = r["max_relative_difference"][key].as_f64().unwrap();
        assert!(d < 1e-4, "{key}: relative difference {d}");
    }
    r
}

/// The number of messages on `topic` in `file` (`slidetrack info`).
fn message_count(file: &Path, topic: &str) -> Option<u64> {
    let info: serde_json::Value =
        serde_json::from_str(&ok(&["info", file.to_str().unwrap(), "--json"])).unwrap();
    info["channels"]
        .as_array()
        .unwrap()
        .iter()
        .find(|c| c["topic"] == topic)
        .map(|c| c["messages"].as_u64().unwrap())
}

/// The `__metadata__` and tensor shapes of a safetensors file's header.
fn safetensors_header(path: &Path) -> (serde_json::Map<String, serde_json::Value>, serde_json::Value) {
    let bytes = std::fs::read(path).unwrap();
    let n = u64::from_le_bytes(bytes[..8].try_into().unwrap()) as usize;
    let mut header: serde_json::Value = serde_json::from_slice(&bytes[8..8 + n]).unwrap();
    let meta = header.as_object_mut().unwrap().remove("__metadata__").unwrap();
    (meta.as_object().unwrap().clone(), header)
}

/// A model with two shared residual blocks, a width of 48 and tanh trains,
/// says so in its file, replays (reproduced by the NumPy reference, which
/// reads the architecture from the file) and evaluates.
#[test]
fn a_model_with_two_blocks_and_tanh_trains_replays_and_evaluates() {
    let dir = tempdir();
    let sessions: Vec<_> =
        (0..3u64).map(|s| collect(dir.path(), "box", 40 + s, 8.0, &["--no-camera"])).collect();
    let model = dir.path().join("tanh.safetensors");
    let m = model.to_str().unwrap();
    let (a, b) = (sessions[0].to_str().unwrap(), sessions[1].to_str().unwrap());
    let summary: serde_json::Value = serde_json::from_str(&ok(&[
        "-q",
        "train",
        a,
        b,
        "--truth",
        "sim",
        "--schedule",
        "2:1,4:1",
        "--threads",
        "1",
        "--blocks",
        "2",
        "--activation",
        "tanh",
        "--width",
        "48",
        "--json",
        "--out",
        m,
    ]))
    .unwrap();
    assert_eq!(
        summary["architecture"],
        serde_json::json!({"width": 48, "residual_blocks": 2, "activation": "tanh"})
    );
    let (meta, tensors) = safetensors_header(&model);
    let arch: serde_json::Value =
        serde_json::from_str(meta["slidetrack.dekf.architecture"].as_str().unwrap()).unwrap();
    assert_eq!(arch, summary["architecture"]);
    assert_eq!(tensors["motion.shared.residual.1.fc2.weight"]["shape"], serde_json::json!([48, 48]));
    assert!(tensors.get("motion.shared.residual.2.fc1.weight").is_none());
    assert_eq!(tensors.as_object().unwrap().len(), 3 * 2 * (5 + 2 * 2) + 4);

    let out = dir.path().join("replay.mcap");
    ok(&["replay", sessions[2].to_str().unwrap(), "--model", m, "--out", out.to_str().unwrap()]);
    let steps = message_count(&out, "/estimate/dekf").expect("estimates");
    assert!(steps > 200, "{steps} dEKF steps");
    let r = check_against_the_reference(m, &out, steps);
    assert_eq!(r["architecture"]["activation"], "tanh");

    let v: serde_json::Value = serde_json::from_str(&ok(&[
        "eval",
        "--model",
        m,
        "--truth",
        "sim",
        sessions[2].to_str().unwrap(),
        "--json",
    ]))
    .unwrap();
    for key in ["position_rmse_cm", "velocity_rmse_cmps", "baseline_position_rmse_cm"] {
        assert!(v[key].as_f64().is_some_and(f64::is_finite), "{key} in {v}");
    }
    // A bad architecture is refused before any work.
    let e = fails(&["train", a, "--truth", "sim", "--width", "0", "--out", m]);
    assert!(e.contains("width 0"), "{e}");
}

#[test]
fn replay_matches_the_reference_implementation_of_the_model_format() {
    let dir = tempdir();
    let (sessions, model) = trained(dir.path());
    let out = dir.path().join("replay.mcap");
    let m = model.to_str().unwrap();
    ok(&["replay", sessions[2].to_str().unwrap(), "--model", m, "--out", out.to_str().unwrap()]);
    // The default model is the thesis's network, and says so.
    let (meta, tensors) = safetensors_header(&model);
    let arch: serde_json::Value =
        serde_json::from_str(meta["slidetrack.dekf.architecture"].as_str().unwrap()).unwrap();
    assert_eq!(arch, serde_json::json!({"width": 64, "residual_blocks": 3, "activation": "relu"}));
    assert_eq!(tensors.as_object().unwrap().len(), 3 * 22 + 4);
    assert_eq!(tensors["feature.shared.residual.2.fc1.weight"]["shape"], serde_json::json!([64, 64]));
    let count = |topic: &str| message_count(&out, topic);
    let steps = count("/estimate/dekf").expect("estimates");
    assert_eq!(count("/tactile/derivative"), Some(steps));
    // One dEKF step per 3 (the decimation) zeroed scans of the replay.
    let zeroed = count("/tactile/zeroed").expect("zeroed scans");
    assert!(zeroed / 3 <= steps && steps <= zeroed / 3 + 1, "{steps} steps for {zeroed} zeroed scans");
    // 12 s of cycles plus setup at 100 Hz, decimated by 3.
    assert!((500..800).contains(&steps), "{steps} dEKF steps");

    let r = check_against_the_reference(m, &out, steps);
    assert_eq!(r["architecture"]["residual_blocks"], 3);
}

#[test]
fn eval_reports_the_documented_keys_and_bad_input_is_refused() {
    let dir = tempdir();
    let (sessions, model) = trained(dir.path());
    let m = model.to_str().unwrap();
    let test = sessions[2].to_str().unwrap();
    let v: serde_json::Value =
        serde_json::from_str(&ok(&["eval", "--model", m, "--truth", "sim", test, "--json"])).unwrap();
    for key in [
        "position_rmse_cm",
        "position_max_cm",
        "velocity_rmse_cmps",
        "velocity_max_cmps",
        "baseline_position_rmse_cm",
    ] {
        assert!(v[key].as_f64().is_some_and(f64::is_finite), "{key} in {v}");
    }
    assert_eq!(v["sessions"].as_array().unwrap().len(), 1);

    // Sessions without ground truth.
    let e = fails(&["eval", "--model", m, test]);
    assert!(e.contains("/ground_truth/sliding") && e.contains("slidetrack label"), "{e}");
    let e = fails(&["train", test, "--out", dir.path().join("x.safetensors").to_str().unwrap()]);
    assert!(e.contains("/ground_truth/sliding"), "{e}");
    // A model file that is not one, and one for another tactile rate.
    let junk = dir.path().join("junk.safetensors");
    std::fs::write(&junk, b"not a model").unwrap();
    let e = fails(&["eval", "--model", junk.to_str().unwrap(), "--truth", "sim", test]);
    assert!(e.contains("junk.safetensors"), "{e}");
    let rig = dir.path().join("fast.toml");
    std::fs::write(&rig, "[sim]\ntactile_rate_hz = 250.0\n[protocol]\ncontrol_rate_hz = 100.0\n").unwrap();
    let fast_dir = dir.path().join("fast");
    let fast = collect(&fast_dir, "box", 30, 3.0, &["--no-camera", "--config", rig.to_str().unwrap()]);
    let e = fails(&["eval", "--model", m, "--truth", "sim", fast.to_str().unwrap()]);
    assert!(e.contains("250") && e.contains("100"), "{e}");
    let e = fails(&["train", test, "--truth", "sim", "--schedule", "2-5", "--out", "x.safetensors"]);
    assert!(e.contains("schedule"), "{e}");
}

/// The rows of a CSV export as numbers (header dropped).
fn numeric_rows(csv: &str) -> Vec<Vec<f64>> {
    csv.lines().skip(1).map(|l| l.split(',').map(|x| x.parse::<f64>().unwrap()).collect()).collect()
}

#[test]
fn track_runs_the_dekf_live_and_replay_reproduces_its_estimates() {
    let dir = tempdir();
    let (_, model) = trained(dir.path());
    let m = model.to_str().unwrap();
    let live = dir.path().join("live.mcap");
    let out = ok(&[
        "track",
        "--model",
        m,
        "--duration",
        "6",
        "--seed",
        "31",
        "--vision",
        "maskukf",
        "--out",
        live.to_str().unwrap(),
    ]);
    assert!(out.contains("dEKF against the simulator's truth"), "{out}");
    assert!(out.contains("marker KF"), "{out}");
    assert!(out.contains("vision (maskukf)"), "{out}");

    let export = |file: &Path, topic: &str| ok(&["export", file.to_str().unwrap(), "--channel", topic]);
    let aruco = numeric_rows(&export(&live, "/estimate/aruco"));
    assert!(aruco.len() > 200, "{} marker estimates in 6 s of cycles at 30 Hz", aruco.len());
    assert!(aruco.iter().flatten().all(|x| x.is_finite()));
    let vision = export(&live, "/estimate/pose/maskukf");
    assert!(vision.lines().count() > 200, "{} vision estimates", vision.lines().count());

    // The same model on the recorded scans gives the same estimates.
    let replayed = dir.path().join("replayed.mcap");
    ok(&["replay", live.to_str().unwrap(), "--model", m, "--out", replayed.to_str().unwrap()]);
    let online = numeric_rows(&export(&live, "/estimate/dekf"));
    let offline = numeric_rows(&export(&replayed, "/estimate/dekf"));
    // Replay stops at the release; the live filter runs to the end of the trial.
    assert!(offline.len() > 150 && online.len() >= offline.len(), "{} vs {}", online.len(), offline.len());
    for (a, b) in online.iter().zip(&offline) {
        assert_eq!(a[0], b[0], "same step times");
        for (x, y) in a.iter().zip(b).skip(1) {
            assert!((x - y).abs() <= 1e-9 * (1.0 + y.abs()), "online {a:?} vs replay {b:?}");
        }
    }
}

#[test]
fn study_quick_writes_the_thesis_tables() {
    let dir = tempdir();
    let out = dir.path().join("study");
    let sessions = dir.path().join("sessions");
    ok(&[
        "-q",
        "study",
        "--quick",
        "--collect",
        "2",
        "--duration",
        "8",
        "--sessions",
        sessions.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    let tables: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("tables.json")).unwrap()).unwrap();
    for (table, columns) in [("Table 6.1", 8), ("Table 6.2", 12), ("Table 6.3", 8), ("Table 6.4", 8)] {
        let t = &tables["tables"][table];
        assert_eq!(t["columns"].as_array().map(Vec::len), Some(columns), "{table}");
        let rows = t["rows"].as_object().unwrap();
        let names: Vec<&str> = rows.keys().map(String::as_str).collect();
        for row in ["bottle", "mustard", "box", "MEAN"] {
            assert!(names.contains(&row), "{table}: rows {names:?}");
            for (column, v) in rows[row].as_object().unwrap() {
                assert!(v.as_f64().is_some_and(f64::is_finite), "{table} {row} {column}: {v}");
            }
        }
    }
    assert_eq!(tables["models"].as_array().map(Vec::len), Some(13));
    let md = std::fs::read_to_string(out.join("tables.md")).unwrap();
    assert!(md.contains("## Table 6.4") && md.contains("| MEAN |"), "{md}");
}

#[test]
fn demo_runs_the_whole_pipeline() {
    let dir = tempdir();
    let out = ok(&[
        "-q",
        "demo",
        "--train",
        "2",
        "--test",
        "1",
        "--duration",
        "8",
        "--out",
        dir.path().to_str().unwrap(),
    ]);
    assert!(out.contains("of the zero-motion baseline"), "{out}");
    for f in ["box-xy.safetensors", "eval.json", "replay.png", "training-curve.png", "ground-truth.png"] {
        assert!(dir.path().join(f).is_file(), "{f} missing:\n{out}");
    }
}

/// The same seed and sessions give the same model file, byte for byte,
/// whatever `--threads` says (a wall time or a thread-dependent reduction
/// order in the file would break it).
#[test]
fn training_on_one_or_two_threads_writes_the_same_file() {
    let dir = tempdir();
    let (sessions, one) = trained(dir.path());
    let two = dir.path().join("two.safetensors");
    let (a, b) = (sessions[0].to_str().unwrap(), sessions[1].to_str().unwrap());
    let args = ["-q", "train", a, b, "--truth", "sim", "--channels", "xy", "--schedule", "2:1,8:1"];
    ok(&[&args[..], &["--threads", "2", "--out", two.to_str().unwrap()]].concat());
    let (a, b) = (std::fs::read(&one).unwrap(), std::fs::read(&two).unwrap());
    assert!(a == b, "model files differ");
}
