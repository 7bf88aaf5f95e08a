//! `slidetrack import xela-psc` on the seven real trials of
//! `../shared/testdata/tactile/xela-psc` (the workspace's sibling
//! `shared/`): every CSV value reaches the session at its row's time and the
//! official MCAP reader finds it there; `info` shows the channels; an
//! existing session is not replaced without `--overwrite`; bad input is a
//! one-line error that leaves no session behind; `label`, `train` and `eval`
//! take the sessions as they take xela-csv ones.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

use common::{fails, ok, tempdir};

/// The dataset folder (seven `data_sample_*` trials).
fn dataset() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/testdata/tactile/xela-psc")
}

/// Per trial (folder order): rows, tactile refreshes, rows with the marker
/// seen, slip rows, fail rows, dropped.
const TRIALS: [(&str, u64, u64, u64, u64, u64, bool); 7] = [
    ("data_sample_2022-02-21-09-58-49", 404, 367, 404, 0, 0, false),
    ("data_sample_2022-02-21-14-10-49", 354, 325, 354, 0, 0, false),
    ("data_sample_2022-02-21-15-29-08", 323, 304, 323, 0, 0, false),
    ("data_sample_2022-02-21-17-22-56", 300, 283, 300, 0, 0, false),
    ("data_sample_2022-02-22-08-10-01", 285, 265, 184, 104, 101, false),
    ("data_sample_2022-02-22-11-23-11", 270, 250, 270, 42, 0, false),
    ("data_sample_2022-02-22-15-15-00", 259, 242, 123, 50, 136, true),
];

/// A trial with slip rows and the marker lost for its last 101 rows.
const SLIPS: &str = "data_sample_2022-02-22-08-10-01";

/// The project's Python: `SLIDETRACK_PYTHON` (which `scripts/test` sets;
/// it must exist), else `target/pyenv` if it is there, else `None` with a
/// message (the Python check is skipped).
fn python_if_available() -> Option<PathBuf> {
    if std::env::var_os("SLIDETRACK_PYTHON").is_some() {
        return Some(common::python());
    }
    let python = Path::new(env!("CARGO_MANIFEST_DIR")).join("target/pyenv/bin/python");
    if python.exists() {
        return Some(python);
    }
    eprintln!(
        "skipping the Python check: SLIDETRACK_PYTHON is unset and {} does not exist (scripts/test sets it)",
        python.display()
    );
    None
}

fn mcap_files(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .map(|d| d.filter_map(|e| e.ok()).map(|e| e.file_name().to_string_lossy().into_owned()).collect())
        .unwrap_or_default();
    names.sort();
    names
}

// Catches: a trial skipped or imported twice, a count that does not match the
// files (rows, tactile refreshes, marker sightings, labels), a channel
// missing from `info`, a `/hand/state` invented for a dataset without a
// gripper width, a CSV value dropped or altered on the way (checked by the
// official reader), and a second import silently replacing the first.
#[test]
fn the_seven_trials_import_with_every_value_for_the_official_reader() {
    let dir = tempdir();
    let out = dir.path().join("sessions");
    let data = dataset();
    let printed =
        ok(&["-q", "import", "xela-psc", data.to_str().unwrap(), "--out", out.to_str().unwrap(), "--json"]);
    let reports: Vec<serde_json::Value> = printed.lines().map(|l| serde_json::from_str(l).unwrap()).collect();
    assert_eq!(reports.len(), 7, "{printed}");
    for (r, &(name, rows, fresh, seen, slip, fail, dropped)) in reports.iter().zip(&TRIALS) {
        assert!(r["session"].as_str().unwrap().ends_with(&format!("{name}.mcap")), "{r}");
        assert_eq!(r["rows"], rows, "{r}");
        assert_eq!(r["shared_rows"], rows, "{r}");
        assert_eq!(r["tactile_refreshes"], fresh, "{r}");
        assert_eq!(r["marker_rows_seen"], seen, "{r}");
        assert_eq!((r["slip_rows"].as_u64(), r["fail_rows"].as_u64()), (Some(slip), Some(fail)), "{r}");
        assert_eq!(r["dropped"], dropped, "{r}");
        let rate = r["rate_hz"].as_f64().unwrap();
        assert!((59.5..60.0).contains(&rate), "{r}");
    }
    assert_eq!(mcap_files(&out).len(), 7);

    let session = out.join(format!("{SLIPS}.mcap"));
    let info: serde_json::Value =
        serde_json::from_str(&ok(&["info", "--json", session.to_str().unwrap()])).unwrap();
    let count = |topic: &str| {
        let channels = info["channels"].as_array().unwrap();
        channels.iter().find(|c| c["topic"] == topic).map(|c| c["messages"].as_u64().unwrap())
    };
    for topic in ["/tactile/raw", "/aruco/detections", "/robot/state", "/robot/ee_pose", "/slip/label"] {
        assert_eq!(count(topic), Some(285), "{topic}: {info}");
    }
    assert_eq!(count("/tactile/tare"), Some(1));
    assert_eq!(count("/tactile/zeroed"), Some(265));
    assert_eq!((count("/markers/marker1/pose"), count("/markers/tf")), (Some(184), Some(184)));
    assert_eq!(count("/hand/state"), None, "the dataset has no gripper width");
    let text = ok(&["info", session.to_str().unwrap()]);
    assert!(text.contains("rig xela-psc") && text.contains("96 values per scan"), "{text}");

    if let Some(python) = python_if_available() {
        for &(name, ..) in &TRIALS {
            let check = Command::new(&python)
                .arg(concat!(env!("CARGO_MANIFEST_DIR"), "/tests/python/check_xela_psc_import.py"))
                .arg(out.join(format!("{name}.mcap")))
                .arg(data.join(name))
                .output()
                .expect("python runs");
            let stdout = String::from_utf8_lossy(&check.stdout);
            assert!(check.status.success(), "{name}: {}\n{stdout}", String::from_utf8_lossy(&check.stderr));
            let summary: serde_json::Value = serde_json::from_str(stdout.trim()).unwrap();
            assert!(summary["values_compared"].as_u64().unwrap() > 35_000, "{name}: {summary}");
        }
    }

    // Importing again refuses to overwrite, and --overwrite replaces.
    let trial = data.join(SLIPS);
    let again = fails(&["import", "xela-psc", trial.to_str().unwrap(), "--out", out.to_str().unwrap()]);
    assert!(again.contains("already exists; pass --overwrite to replace it"), "{again}");
    ok(&["-q", "import", "xela-psc", trial.to_str().unwrap(), "--out", out.to_str().unwrap(), "--overwrite"]);
    assert_eq!(mcap_files(&out).len(), 7, "no temporary file left: {:?}", mcap_files(&out));
}

/// A copy of [`SLIPS`] in `dir`, with `edit` applied.
fn broken_copy(dir: &Path, edit: impl FnOnce(&Path)) -> PathBuf {
    let copy = dir.join("data_sample_broken");
    std::fs::create_dir_all(&copy).expect("a writable temporary folder");
    for entry in std::fs::read_dir(dataset().join(SLIPS)).expect("the trial") {
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

fn set_field(path: &Path, line: usize, col: usize, value: &str) {
    replace_line(path, line, |l| {
        let mut f: Vec<&str> = l.split(',').collect();
        f[col] = value;
        f.join(",")
    });
}

// Catches: a panic or a multi-line dump on bad input, an error that does not
// say where, a time column that goes back accepted (messages out of order),
// and a session file (or a temporary one) left behind by a failed import.
#[test]
fn bad_input_is_a_one_line_error_naming_the_place_and_writes_nothing() {
    type Edit = Box<dyn FnOnce(&Path)>;
    let cases: Vec<(&str, Edit, &str)> = vec![
        (
            "non-numeric field",
            Box::new(|d: &Path| set_field(&d.join("robot_state.csv"), 5, 2, "0.1x")),
            "robot_state.csv:5: column 3 (position_joint3): not a number: \"0.1x\"",
        ),
        (
            "bad header",
            Box::new(|d: &Path| {
                replace_line(&d.join("xela_sensor2.csv"), 1, |l| l.replacen("txl1_x", "txl1_q", 1))
            }),
            "xela_sensor2.csv:1: column 1 is \"txl1_q\", expected \"txl1_x\"",
        ),
        (
            "missing file",
            Box::new(|d: &Path| std::fs::remove_file(d.join("slip_label.csv")).unwrap()),
            "slip_label.csv: cannot open",
        ),
        (
            "short row",
            Box::new(|d: &Path| replace_line(&d.join("marker.csv"), 9, |_| "0.1,0.2,0.3".into())),
            "marker.csv:9: expected 7 fields as in the header, found 3",
        ),
        (
            "time goes back",
            Box::new(|d: &Path| set_field(&d.join("robot_state.csv"), 100, 32, "0.5")),
            "robot_state.csv:100: column 33 (time): time goes back",
        ),
    ];
    for (what, edit, expected) in cases {
        let dir = tempdir();
        let copy = broken_copy(dir.path(), edit);
        let out = dir.path().join("out");
        let stderr = fails(&["import", "xela-psc", copy.to_str().unwrap(), "--out", out.to_str().unwrap()]);
        assert!(stderr.contains(expected), "{what}: {stderr}");
        assert!(mcap_files(&out).is_empty(), "{what}: left {:?}", mcap_files(&out));
    }
}

// Catches: `label` needing what these sessions lack (a hand state, a
// protocol, a rate), a ground truth that does not cover every tactile row or
// ignores the rows where the marker is lost, and train/eval refusing the
// sessions (their tactile refresh rates must agree within the default 5 %).
#[test]
fn label_train_and_eval_take_the_imported_trials() {
    let dir = tempdir();
    let (train, test) = (dir.path().join("train"), dir.path().join("test"));
    let data = dataset();
    let trials: Vec<String> = TRIALS.iter().map(|t| data.join(t.0).display().to_string()).collect();
    let (held_out, rest) = (&trials[5], [&trials[..5], &trials[6..]].concat());
    let mut args = vec!["-q", "import", "xela-psc"];
    args.extend(rest.iter().map(String::as_str));
    args.extend(["--out", train.to_str().unwrap()]);
    ok(&args);
    ok(&["-q", "import", "xela-psc", held_out, "--out", test.to_str().unwrap()]);

    let session = train.join(format!("{SLIPS}.mcap"));
    let dry: serde_json::Value =
        serde_json::from_str(&ok(&["label", session.to_str().unwrap(), "--dry-run", "--json"])).unwrap();
    let r = &dry[0];
    assert_eq!((r["samples"].as_u64(), r["camera_frames"].as_u64()), (Some(285), Some(285)), "{dry}");
    assert_eq!((r["marker_positions"].as_u64(), r["missing_detections"].as_u64()), (Some(184), Some(101)));
    assert_eq!(r["written"], false, "{dry}");

    let files: Vec<String> = mcap_files(&train)
        .iter()
        .map(|n| train.join(n))
        .chain([test.join(format!("{}.mcap", TRIALS[5].0))])
        .map(|p| p.display().to_string())
        .collect();
    let mut label = vec!["-q", "label"];
    label.extend(files.iter().map(String::as_str));
    ok(&label);
    let model = dir.path().join("m.safetensors");
    ok(&[
        "-q",
        "train",
        train.to_str().unwrap(),
        "--channels",
        "sensor1.mean.z,sensor2.mean.z,sensor1.mean.x,sensor2.mean.y",
        "--schedule",
        "2:1,4:1",
        "--threads",
        "1",
        "--out",
        model.to_str().unwrap(),
    ]);
    let report: serde_json::Value = serde_json::from_str(&ok(&[
        "eval",
        "--model",
        model.to_str().unwrap(),
        test.to_str().unwrap(),
        "--json",
    ]))
    .unwrap();
    let s = &report["sessions"][0];
    assert!(s["steps"].as_u64().unwrap() > 100, "{report}");
    assert!(s["position_rmse_cm"].as_f64().unwrap().is_finite(), "{report}");
}
