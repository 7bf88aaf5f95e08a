//! `slidetrack import xela-csv` on the real recordings of
//! `../shared/testdata/tactile/xela-imanlab` (the workspace's sibling
//! `shared/`): every CSV value reaches the session and the official MCAP
//! reader finds it there; bad input is a one-line error that leaves no
//! session behind; `label` bridges the rows where marker 1 is not seen.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

use common::{fails, ok, python, tempdir};
use slidetrack_session::{ArucoDetection, GroundTruthSliding, ReadOptions, TactileRaw, read_channel};

/// A sequence folder of the dataset (`train/...` or `test/...`).
fn sequence(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/testdata/tactile/xela-imanlab").join(rel)
}

/// One extra tactile row (the tail), marker 2 lost for a while.
const WITH_TAIL: &str = "train/data_sample_2021-11-24-15-19-34";
/// Marker 1 unseen on half the rows, the longest gap 326 rows (7.7 s).
const LONG_GAPS: &str = "train/data_sample_2021-11-24-15-21-15";
/// Marker 2 never seen, no `meta_data.csv.npy`.
const NO_NPY: &str = "train/data_sample_2021-11-24-15-55-09";
/// The dataset's test sequence (a `notes` column, `seen` 0).
const TEST: &str = "test/data_sample_2021-11-25-13-09-52";

fn session_of(out: &Path, rel: &str) -> PathBuf {
    out.join(format!("{}.mcap", Path::new(rel).file_name().and_then(|n| n.to_str()).expect("a folder name")))
}

fn mcap_files(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .map(|d| d.filter_map(|e| e.ok()).map(|e| e.file_name().to_string_lossy().into_owned()).collect())
        .unwrap_or_default();
    names.sort();
    names
}

// Catches: a CSV value dropped or altered on the way (a taxel out of place,
// x/y/z swapped, the tail row lost, a marker pose written for a 10.0
// sentinel or missing for a real one, a robot column shifted, a metadata
// column or the npy path missing), and a file the official reader rejects.
#[test]
fn imported_sequences_hold_every_csv_value_for_the_official_reader() {
    let dir = tempdir();
    let out = dir.path().join("sessions");
    let rels = [WITH_TAIL, LONG_GAPS, NO_NPY, TEST];
    let dirs: Vec<String> = rels.iter().map(|r| sequence(r).display().to_string()).collect();
    let mut args = vec!["-q", "import", "xela-csv"];
    args.extend(dirs.iter().map(String::as_str));
    args.extend(["--out", out.to_str().unwrap(), "--json"]);
    let printed = ok(&args);
    assert_eq!(printed.lines().count(), rels.len(), "{printed}");
    for rel in rels {
        let session = session_of(&out, rel);
        let check = Command::new(python())
            .arg(concat!(env!("CARGO_MANIFEST_DIR"), "/tests/python/check_xela_import.py"))
            .arg(&session)
            .arg(sequence(rel))
            .output()
            .expect("python runs");
        let stdout = String::from_utf8_lossy(&check.stdout);
        assert!(check.status.success(), "{rel}: {}\n{stdout}", String::from_utf8_lossy(&check.stderr));
        let summary: serde_json::Value = serde_json::from_str(stdout.trim()).unwrap();
        assert!(summary["values_compared"].as_u64().unwrap() > 20_000, "{rel}: {summary}");
        let info = ok(&["info", session.to_str().unwrap()]);
        assert!(info.contains("32 taxels, 96 values per scan"), "{info}");
        assert!(info.contains("/markers/marker1/pose") && info.contains("/robot/state"), "{info}");
    }
    // The tail row: 1064 tactile rows for 1063 robot and marker rows.
    let raw = read_channel::<TactileRaw>(&session_of(&out, WITH_TAIL), ReadOptions::default()).unwrap();
    assert_eq!(raw.len(), 1064);
    assert_eq!(
        raw.iter().map(|(_, r)| r.sensors.iter().map(|s| s.taxels.len() * 3).sum::<usize>()).max(),
        Some(96)
    );
    // Importing again refuses to overwrite, and --overwrite replaces.
    let again = fails(&["import", "xela-csv", &dirs[3], "--out", out.to_str().unwrap()]);
    assert!(again.contains("already exists"), "{again}");
    ok(&["-q", "import", "xela-csv", &dirs[3], "--out", out.to_str().unwrap(), "--overwrite"]);
}

/// A copy of the test sequence in `dir`, with `edit` applied.
fn broken_copy(dir: &Path, edit: impl FnOnce(&Path)) -> PathBuf {
    let copy = dir.join("data_sample_broken");
    std::fs::create_dir_all(&copy).expect("a writable temporary folder");
    for entry in std::fs::read_dir(sequence(TEST)).expect("the test sequence") {
        let entry = entry.expect("a readable folder entry");
        std::fs::copy(entry.path(), copy.join(entry.file_name())).expect("a copied file");
    }
    edit(&copy);
    copy
}

fn replace_line(path: &Path, line: usize, f: impl FnOnce(&str) -> String) {
    let text = std::fs::read_to_string(path).expect("a readable CSV");
    let mut lines: Vec<String> = text.lines().map(str::to_owned).collect();
    lines[line - 1] = f(&lines[line - 1]);
    std::fs::write(path, lines.join("\n") + "\n").expect("a writable CSV");
}

// Catches: a panic or a multi-line dump on bad input, an error that does not
// say where, and a session file (or a temporary one) left behind by an
// import that failed, as if it were complete.
#[test]
fn bad_input_is_a_one_line_error_naming_the_place_and_writes_nothing() {
    type Edit = Box<dyn FnOnce(&Path)>;
    let cases: Vec<(&str, Edit, &str)> = vec![
        (
            "bad number",
            Box::new(|d: &Path| {
                replace_line(&d.join("robot_state.csv"), 5, |l| {
                    let mut f: Vec<&str> = l.split(',').collect();
                    f[2] = "0.1x";
                    f.join(",")
                })
            }),
            "robot_state.csv:5: column 3 (position_panda_joint3)",
        ),
        (
            "bad header",
            Box::new(|d: &Path| {
                replace_line(&d.join("xela_sensor2.csv"), 1, |l| l.replacen("txl1_x", "txl1_q", 1))
            }),
            "xela_sensor2.csv:1: column 1",
        ),
        (
            "missing file",
            Box::new(|d: &Path| std::fs::remove_file(d.join("marker.csv")).unwrap()),
            "marker.csv",
        ),
    ];
    for (what, edit, expected) in cases {
        let dir = tempdir();
        let copy = broken_copy(dir.path(), edit);
        let out = dir.path().join("out");
        let stderr = fails(&["import", "xela-csv", copy.to_str().unwrap(), "--out", out.to_str().unwrap()]);
        assert!(stderr.contains(expected), "{what}: {stderr}");
        assert_eq!(stderr.trim().lines().count(), 1, "{what}: {stderr}");
        assert!(!stderr.contains("panicked"), "{what}: {stderr}");
        assert!(mcap_files(&out).is_empty(), "{what}: left {:?}", mcap_files(&out));
    }
}

// Catches: a ground truth that stops, jumps or goes missing where marker 1
// is not seen (no smoothing across the gaps), and one that does not follow
// the marker where it is seen (wrong axis, wrong origin, a time shift).
#[test]
fn labelling_an_imported_sequence_bridges_the_unseen_rows_and_follows_marker_1() {
    let dir = tempdir();
    let out = dir.path();
    ok(&["-q", "import", "xela-csv", sequence(LONG_GAPS).to_str().unwrap(), "--out", out.to_str().unwrap()]);
    let session = session_of(out, LONG_GAPS);
    ok(&["-q", "label", session.to_str().unwrap(), "--no-gate"]);
    let read = ReadOptions::default();
    let gt = read_channel::<GroundTruthSliding>(&session, read).unwrap();
    let scans = read_channel::<TactileRaw>(&session, read).unwrap();
    let detections = read_channel::<ArucoDetection>(&session, read).unwrap();
    assert_eq!(gt.len(), scans.len(), "one ground-truth sample per tactile row");

    // The longest run of rows without marker 1.
    let (mut longest, mut run, mut end) = (0, 0, 0);
    for (i, (_, d)) in detections.iter().enumerate() {
        run = if d.detected { 0 } else { run + 1 };
        if run > longest {
            (longest, end) = (run, i);
        }
    }
    assert!(longest >= 300, "the sequence has a long gap ({longest} rows)");
    // Across it the ground truth is continuous: no step larger than what a
    // smooth motion covers in one row (1 cm), and it ends where the marker
    // is found again.
    let p: Vec<f64> = gt.iter().map(|(_, g)| g.position).collect();
    let gap = end + 1 - longest..end + 1;
    for i in gap.start..gap.end.min(p.len() - 1) {
        assert!(p[i].is_finite() && (p[i + 1] - p[i]).abs() < 0.01, "row {i}: {} -> {}", p[i], p[i + 1]);
    }
    // Where marker 1 is seen, the ground truth is its position along the
    // axis relative to its first sighting, within the smoothing.
    let first = detections.iter().find_map(|(_, d)| d.position_on_axis_m).unwrap();
    let mut errors: Vec<f64> = detections
        .iter()
        .zip(&p)
        .filter_map(|((_, d), gt)| d.position_on_axis_m.map(|m| (gt - (m - first)).abs()))
        .collect();
    errors.sort_by(f64::total_cmp);
    let median = errors[errors.len() / 2];
    let p95 = errors[errors.len() * 95 / 100];
    assert!(median < 0.002 && p95 < 0.01, "median {median} m, p95 {p95} m over {} rows", errors.len());
    let span =
        p.iter().copied().fold(f64::NEG_INFINITY, f64::max) - p.iter().copied().fold(f64::INFINITY, f64::min);
    assert!(span > 0.02, "the object moves along the axis ({span} m)");
}

// Catches: train or eval needing what imported sessions lack (protocol
// events, a release, a common 5 % rate) or eval replaying a protocol that
// never ran; and a rate tolerance that is not kept in the model (eval would
// then refuse the sessions the model was trained to accept).
#[test]
fn train_and_eval_run_on_imported_labelled_sequences() {
    let dir = tempdir();
    let (train, test) = (dir.path().join("train"), dir.path().join("test"));
    let train_dirs: Vec<String> =
        [WITH_TAIL, NO_NPY, LONG_GAPS].iter().map(|r| sequence(r).display().to_string()).collect();
    let mut args = vec!["-q", "import", "xela-csv"];
    args.extend(train_dirs.iter().map(String::as_str));
    args.extend(["--out", train.to_str().unwrap()]);
    ok(&args);
    ok(&["-q", "import", "xela-csv", sequence(TEST).to_str().unwrap(), "--out", test.to_str().unwrap()]);
    let mut label = vec!["-q", "label"];
    let files: Vec<String> = [WITH_TAIL, NO_NPY, LONG_GAPS]
        .iter()
        .map(|r| session_of(&train, r))
        .chain([session_of(&test, TEST)])
        .map(|p| p.display().to_string())
        .collect();
    label.extend(files.iter().map(String::as_str));
    ok(&label);
    let model = dir.path().join("m.safetensors");
    let common = [
        "-q",
        "train",
        train.to_str().unwrap(),
        "--channels",
        "sensor1.mean.z,sensor2.mean.z,sensor1.mean.x,sensor2.mean.y",
        "--rate-hz",
        "10",
        "--schedule",
        "2:1,4:1",
        "--threads",
        "1",
        "--out",
        model.to_str().unwrap(),
    ];
    // 10.0 and 7.9 Hz of tactile refreshes: more than the default 5 % apart.
    let refused = fails(&common);
    assert!(refused.contains("--rate-tolerance"), "{refused}");
    ok(&[&common[..], &["--rate-tolerance", "0.3"]].concat());
    let report: serde_json::Value = serde_json::from_str(&ok(&[
        "eval",
        "--model",
        model.to_str().unwrap(),
        test.to_str().unwrap(),
        "--json",
    ]))
    .unwrap();
    let s = &report["sessions"][0];
    assert!(s["steps"].as_u64().unwrap() > 40, "{report}");
    assert!(s["position_rmse_cm"].as_f64().unwrap().is_finite(), "{report}");
    assert!(s["baseline_position_rmse_cm"].as_f64().unwrap() > 0.0, "{report}");
}
