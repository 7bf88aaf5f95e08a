//! `slidetrack calibrate tactile` end to end on the simulated rig: collect
//! trials with reference forces (fixed sensor hardware, new baselines every
//! grasp), fit on some, measure on held-out ones against the trivial maps,
//! apply the file offline and online.
//!
//! The judged line: the fit predicts held-out forces within 5 % of their
//! range, per axis. Run with `--nocapture` to see the numbers.

mod common;

use std::path::{Path, PathBuf};

use common::{fails, ok, tempdir};
use serde_json::Value;
use slidetrack_session::{ReadOptions, TactileCalibrated, TactileReference, TactileZeroed, read_channel};

const SEED: u64 = 7;
const TRIALS: u32 = 6;
const FIT_TRIALS: u32 = 4;

/// The simulated rig with reference forces and fixed sensor hardware.
const RIG: &str = "[sim]\nreference_forces = true\n[sim.tactile]\nhardware_seed = 11\n";

fn trial_path(dir: &Path, trial: u32) -> PathBuf {
    dir.join(format!("box-s{SEED}-t{trial:03}.mcap"))
}

fn collect(dir: &Path, config: &Path, first_trial: u32, trials: u32) {
    let (first, n) = (first_trial.to_string(), trials.to_string());
    let seed = SEED.to_string();
    let out = dir.to_str().expect("utf-8 path");
    let config = config.to_str().expect("utf-8 path");
    ok(&[
        "-q",
        "collect",
        "--config",
        config,
        "--duration",
        "10",
        "--seed",
        &seed,
        "--no-camera",
        "--trials",
        &n,
        "--first-trial",
        &first,
        "--out",
        out,
    ]);
}

/// The row of `map` in the JSON report.
fn row<'a>(report: &'a Value, map: &str) -> &'a Value {
    report["maps"].as_array().expect("maps").iter().find(|m| m["map"] == map).expect("the map's row")
}

fn fractions(row: &Value) -> [f64; 3] {
    let v = row["rms_of_range"].as_array().expect("rms_of_range");
    [0, 1, 2].map(|i| v[i].as_f64().unwrap_or(f64::INFINITY))
}

#[test]
fn the_fit_predicts_held_out_forces_within_5_percent_of_their_range() {
    let dir = tempdir();
    let rig = dir.path().join("rig.toml");
    std::fs::write(&rig, RIG).unwrap();
    collect(dir.path(), &rig, 0, TRIALS);
    let fit: Vec<PathBuf> = (0..FIT_TRIALS).map(|t| trial_path(dir.path(), t)).collect();
    let eval: Vec<PathBuf> = (FIT_TRIALS..TRIALS).map(|t| trial_path(dir.path(), t)).collect();
    let cal = dir.path().join("tactile-calibration.toml");
    let mut args = vec!["calibrate", "tactile", "--json", "--out", cal.to_str().unwrap(), "--fit"];
    args.extend(fit.iter().map(|p| p.to_str().unwrap()));
    args.push("--eval");
    args.extend(eval.iter().map(|p| p.to_str().unwrap()));
    let report: Value = serde_json::from_str(&ok(&args)).unwrap();
    println!(
        "held-out scans {}, RMS error per axis x y z as a fraction of the reference range:",
        report["eval_scans"]
    );
    for m in report["maps"].as_array().unwrap() {
        println!(
            "  {:<15} {:?}  RMS {} N, range {} N",
            m["map"].as_str().unwrap(),
            fractions(m),
            m["rms_n"],
            m["range_n"]
        );
    }
    assert_eq!(report["held_out"], true);
    let quadratic = fractions(row(&report, "quadratic"));
    let zero = fractions(row(&report, "zero"));
    for (axis, (q, z)) in ["x", "y", "z"].iter().zip(quadratic.iter().zip(zero)) {
        assert!(*q <= 0.05, "axis {axis}: {q:.4} of the range");
        assert!(z > 3.0 * q, "the zero map is no competitor on axis {axis}: {zero:?}");
    }
    let file = std::fs::read_to_string(&cal).unwrap();
    assert!(
        file.contains("format = \"slidetrack.tactile_force_calibration\"") && file.contains("version = 1")
    );

    // Offline: the held-out trial through the file.
    let applied = dir.path().join("applied.mcap");
    let held_out = trial_path(dir.path(), FIT_TRIALS);
    let cal_s = cal.to_str().unwrap();
    ok(&[
        "-q",
        "calibrate",
        "tactile",
        "--apply",
        held_out.to_str().unwrap(),
        "--calibration",
        cal_s,
        "--out",
        applied.to_str().unwrap(),
    ]);
    let offline = read_channel::<TactileCalibrated>(&applied, ReadOptions::default()).unwrap();
    let zeroed = read_channel::<TactileZeroed>(&held_out, ReadOptions::default()).unwrap();
    assert_eq!(offline.len(), zeroed.len(), "a force for every tared scan");
    let reference = read_channel::<TactileReference>(&applied, ReadOptions::default()).unwrap();
    let last = offline.last().unwrap();
    let at_last = reference.iter().find(|(t, _)| *t == last.0).unwrap();
    let (got, want) = (&last.1.sensors[0].taxels[0], &at_last.1.sensors[0].taxels[0]);
    assert!((got.z - want.z).abs() < 0.1 * want.z.abs().max(0.1), "{got:?} vs {want:?}");

    // Online: the same trial recorded on a rig that names the file (relative to the rig TOML).
    let online_dir = dir.path().join("online");
    std::fs::create_dir(&online_dir).unwrap();
    std::fs::copy(&cal, online_dir.join("cal.toml")).unwrap();
    let online_rig = online_dir.join("rig.toml");
    std::fs::write(&online_rig, format!("tactile_calibration = \"cal.toml\"\n{RIG}")).unwrap();
    collect(&online_dir, &online_rig, FIT_TRIALS, 1);
    let online =
        read_channel::<TactileCalibrated>(trial_path(&online_dir, FIT_TRIALS), ReadOptions::default())
            .unwrap();
    assert_eq!(online, offline, "online and offline give the same forces");
}

#[test]
fn bad_input_gives_one_clear_line() {
    let dir = tempdir();
    let session = common::collect(dir.path(), "box", 2, 1.0, &["--no-camera"]);
    let e = fails(&["calibrate", "tactile", "--fit", session.to_str().unwrap()]);
    assert!(e.contains("no reference forces") && e.contains("box-s2-t000.mcap"), "{e}");
    let rig = dir.path().join("rig.toml");
    std::fs::write(&rig, "tactile_calibration = \"missing.toml\"\n").unwrap();
    let e = fails(&[
        "collect",
        "--config",
        rig.to_str().unwrap(),
        "--no-camera",
        "--out",
        dir.path().to_str().unwrap(),
    ]);
    assert!(e.contains("tactile_calibration") && e.contains("missing.toml"), "{e}");
    let bad = dir.path().join("bad.toml");
    std::fs::write(&bad, "format = \"slidetrack.tactile_force_calibration\"\nversion = 9\n").unwrap();
    let out = dir.path().join("out.mcap");
    let e = fails(&[
        "calibrate",
        "tactile",
        "--apply",
        session.to_str().unwrap(),
        "--calibration",
        bad.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(e.contains("bad.toml"), "{e}");
}
