//! `slidetrack label` end to end on simulated sessions: the ground truth
//! meets the accuracy targets against the simulator's truth, labelling
//! loses nothing and is idempotent, and bad input leaves files untouched.

mod common;

use std::path::Path;

use common::{collect, fails, ok, run, tempdir};
use serde_json::Value;
use slidetrack_core::TimeNs;
use slidetrack_session::{
    ArucoDetection, GroundTruthMeasurement, GroundTruthSliding, MessageReader, NewChannel, ReadOptions,
    SessionInfo, TactileRaw, read_channel, rewrite_session,
};

/// Every message not under /ground_truth/: topic, times, sequence, payload.
fn other_messages(path: &Path) -> Vec<(String, TimeNs, TimeNs, u32, Vec<u8>)> {
    MessageReader::open(path, &[], ReadOptions::default())
        .expect("readable session")
        .map(|m| m.expect("readable message"))
        .filter(|m| !m.topic().starts_with("/ground_truth/"))
        .map(|m| (m.topic().to_string(), m.log_time, m.publish_time, m.sequence, m.data))
        .collect()
}

#[test]
fn a_simulated_session_is_labelled_within_the_targets_losslessly_and_idempotently() {
    let dir = tempdir();
    let file = collect(dir.path(), "box", 3, 20.0, &[]);
    let path = file.to_str().unwrap();
    let before = other_messages(&file);
    let info_before = SessionInfo::read(&file, ReadOptions::default()).unwrap();

    let out: Value = serde_json::from_str(&ok(&["-q", "label", path, "--json"])).unwrap();
    let summary = &out[0];
    let scans = read_channel::<TactileRaw>(&file, ReadOptions::default()).unwrap();
    assert_eq!(summary["samples"].as_u64(), Some(scans.len() as u64));
    let rmse_p = summary["rmse"]["position_m"].as_f64().unwrap();
    let rmse_v = summary["rmse"]["velocity_mps"].as_f64().unwrap();
    // About twice the errors measured on this session (0.04-0.08 mm,
    // 0.12-0.17 mm/s), so that a worse smoother fails.
    eprintln!("ground truth vs /sim/truth: {:.3} mm, {:.3} mm/s", rmse_p * 1e3, rmse_v * 1e3);
    assert!(rmse_p <= 0.16e-3, "position RMSE {:.3} mm", rmse_p * 1e3);
    assert!(rmse_v <= 0.35e-3, "velocity RMSE {:.3} mm/s", rmse_v * 1e3);
    assert!(summary["marker_positions"].as_u64().unwrap() > 500, "{summary}");

    // Nothing else changed: messages, metadata, attachments.
    assert_eq!(other_messages(&file), before);
    let info = SessionInfo::read(&file, ReadOptions::default()).unwrap();
    assert_eq!(info.metadata, info_before.metadata);
    assert_eq!(info.attachments, info_before.attachments);
    let sliding = read_channel::<GroundTruthSliding>(&file, ReadOptions::default()).unwrap();
    let times: Vec<TimeNs> = sliding.iter().map(|(t, _)| *t).collect();
    assert_eq!(times, scans.iter().map(|(t, _)| *t).collect::<Vec<_>>(), "one ground truth per tactile scan");
    let measured = read_channel::<GroundTruthMeasurement>(&file, ReadOptions::default()).unwrap();
    assert_eq!(measured.len() as u64, summary["marker_positions"].as_u64().unwrap());
    assert_eq!(measured[0].1.position, 0.0, "the first marker position is the origin");
    let channel = info.channels.iter().find(|c| c.topic == "/ground_truth/sliding").unwrap();
    let params: Value = serde_json::from_str(&channel.metadata["parameters"]).unwrap();
    for key in
        ["q_position_m2_per_s", "q_velocity_m2_per_s3", "r_m2", "x0", "p0", "gate_max_mahalanobis2", "units"]
    {
        assert!(params.get(key).is_some(), "parameters lack {key}: {params}");
    }

    // Labelling again gives the same bytes.
    let first = std::fs::read(&file).unwrap();
    ok(&["-q", "label", path]);
    assert_eq!(std::fs::read(&file).unwrap(), first);

    // The axis from the stored rig config gives the same positions as recorded online.
    let text = ok(&["-q", "label", path, "--axis", "config", "--dry-run"]);
    assert!(text.contains("dry run") && text.contains("RMSE"), "{text}");
    assert_eq!(std::fs::read(&file).unwrap(), first, "a dry run writes nothing");

    // Figure 6.5.
    let png = dir.path().join("gt.png");
    ok(&["plot", path, "--what", "ground-truth", "--out", png.to_str().unwrap()]);
    assert!(std::fs::metadata(&png).unwrap().len() > 10_000);
}

#[test]
fn sessions_without_marker_detections_are_refused_and_left_untouched() {
    let dir = tempdir();
    let file = collect(dir.path(), "box", 5, 2.0, &["--no-camera"]);
    let path = file.to_str().unwrap();
    let bytes = std::fs::read(&file).unwrap();
    let e = fails(&["label", path]);
    assert!(e.contains("without a camera") && e.contains(path), "{e}");
    assert_eq!(std::fs::read(&file).unwrap(), bytes);
    let e =
        fails(&["plot", path, "--what", "ground-truth", "--out", dir.path().join("x.png").to_str().unwrap()]);
    assert!(e.contains("slidetrack label"), "{e}");

    // A truncated copy is refused (and kept) without --recover.
    let cut = dir.path().join("cut.mcap");
    std::fs::write(&cut, &bytes[..bytes.len() / 2]).unwrap();
    let e = fails(&["label", cut.to_str().unwrap()]);
    assert!(e.contains("truncated"), "{e}");
    assert_eq!(std::fs::read(&cut).unwrap(), &bytes[..bytes.len() / 2]);
    // A camera channel in which the marker was never found.
    let blind = collect(dir.path(), "bottle", 6, 2.0, &[]);
    let frames = read_channel::<ArucoDetection>(&blind, ReadOptions::default()).unwrap();
    let mut missed = NewChannel::of::<ArucoDetection>(Default::default());
    for (t, _) in &frames {
        missed.push_json(*t, &ArucoDetection::missed()).unwrap();
    }
    rewrite_session(&blind, ReadOptions::default(), &|_| false, vec![missed]).unwrap();
    let blind_bytes = std::fs::read(&blind).unwrap();
    let e = fails(&["label", blind.to_str().unwrap()]);
    assert!(e.contains(&format!("no marker position in any of the {} camera frame", frames.len())), "{e}");
    assert_eq!(std::fs::read(&blind).unwrap(), blind_bytes);
    // Several files: each failure named on its own line, then the count; exit 1.
    let out = run(&["-q", "label", blind.to_str().unwrap(), path]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("2 of 2 files could not be labelled (left unchanged)"), "{stderr}");
    assert!(stderr.lines().any(|l| l.contains("without a camera")), "{stderr}");
    let e = fails(&["label", dir.path().join("none.mcap").to_str().unwrap()]);
    assert!(e.contains("none.mcap"), "{e}");
    let names: Vec<_> = std::fs::read_dir(dir.path()).unwrap().map(|e| e.unwrap().file_name()).collect();
    assert!(names.iter().all(|n| !n.to_string_lossy().ends_with(".tmp")), "{names:?}");
}

/// `--tune` chooses the smoother's noise from the marker positions alone
/// (the simulator's truth is read only to score it), from the defaults and
/// from the thesis's values alike, and records what it chose.
#[test]
fn tuned_ground_truth_meets_the_targets_without_the_simulators_truth() {
    let dir = tempdir();
    let file = collect(dir.path(), "box", 5, 20.0, &[]);
    let path = file.to_str().unwrap();
    for start in [&[][..], &["--thesis"][..]] {
        let args = [&["-q", "label", path, "--tune", "--json"][..], start].concat();
        let out: Value = serde_json::from_str(&ok(&args)).unwrap();
        let s = &out[0];
        let (p, v) = (s["rmse"]["position_m"].as_f64().unwrap(), s["rmse"]["velocity_mps"].as_f64().unwrap());
        eprintln!("tuned from {start:?}: {:.3} mm, {:.3} mm/s; {}", p * 1e3, v * 1e3, s["params"]);
        // The targets of the issue are 1 mm / 5 mm/s; measured 0.06 mm,
        // 0.13 mm/s from either start: fail at about twice that.
        assert!(p <= 0.15e-3 && v <= 0.35e-3, "from {start:?}: {p} m, {v} m/s");
        assert_eq!(s["params"]["tuned"], true);
        assert_eq!(s["params"]["gate_max_mahalanobis2"], 25.0, "tuned with the gate");
    }
    let info = SessionInfo::read(&file, ReadOptions::default()).unwrap();
    let channel = info.channels.iter().find(|c| c.topic == "/ground_truth/sliding").unwrap();
    let params: Value = serde_json::from_str(&channel.metadata["parameters"]).unwrap();
    assert!(params["tuning"].as_str().unwrap().contains("maximum marginal likelihood"), "{params}");
    assert_ne!(params["r_m2"].as_f64(), Some(2.5e-7), "the tuned R, not the default: {params}");
}

/// `--tune --jointly` estimates one set of parameters for all the files:
/// each is labelled with the same values, within the targets, and records
/// that they were tuned over the sessions; the joint log-likelihood is the
/// sum of the sessions'. A file that cannot be read stops it before any file
/// is written.
#[test]
fn joint_tuning_labels_every_session_with_one_estimate() {
    let dir = tempdir();
    let a = collect(dir.path(), "box", 5, 12.0, &[]);
    let b = collect(dir.path(), "bottle", 6, 12.0, &[]);
    let (pa, pb) = (a.to_str().unwrap(), b.to_str().unwrap());
    let blind = collect(dir.path(), "mustard", 7, 2.0, &["--no-camera"]);
    let (a_bytes, blind_bytes) = (std::fs::read(&a).unwrap(), std::fs::read(&blind).unwrap());
    let e = fails(&["label", pa, blind.to_str().unwrap(), "--tune", "--jointly"]);
    assert!(e.contains("without a camera") && e.contains(blind.to_str().unwrap()), "{e}");
    assert_eq!(std::fs::read(&a).unwrap(), a_bytes, "a file was written before the tuning failed");
    assert_eq!(std::fs::read(&blind).unwrap(), blind_bytes);
    let usage = run(&["label", pa, "--jointly"]);
    let e = String::from_utf8_lossy(&usage.stderr);
    assert!(usage.status.code() == Some(2) && e.contains("--tune"), "{e}");

    let out: Value =
        serde_json::from_str(&ok(&["-q", "label", pa, pb, "--tune", "--jointly", "--json"])).unwrap();
    let joint = &out["joint_tuning"];
    assert_eq!(joint["sessions"], 2, "{out}");
    let sessions = out["sessions"].as_array().unwrap();
    let mut sum = 0.0;
    for s in sessions {
        let (p, v) = (s["rmse"]["position_m"].as_f64().unwrap(), s["rmse"]["velocity_mps"].as_f64().unwrap());
        eprintln!("{}: {:.3} mm, {:.3} mm/s; {}", s["file"], p * 1e3, v * 1e3, s["params"]);
        assert!(p <= 0.15e-3 && v <= 0.35e-3, "{}: {p} m, {v} m/s", s["file"]);
        for k in ["q_position_m2_per_s", "q_velocity_m2_per_s3", "r_m2"] {
            assert_eq!(s["params"][k], joint[k], "{k}");
        }
        sum += s["params"]["log_likelihood"].as_f64().unwrap();
    }
    let total = joint["log_likelihood"].as_f64().unwrap();
    assert!((total - sum).abs() < 1e-6 * total.abs(), "joint {total}, sum of the sessions {sum}");
    let positions: u64 = sessions.iter().map(|s| s["marker_positions"].as_u64().unwrap()).sum();
    assert_eq!(joint["marker_positions"].as_u64(), Some(positions));
    for file in [&a, &b] {
        let info = SessionInfo::read(file, ReadOptions::default()).unwrap();
        let channel = info.channels.iter().find(|c| c.topic == "/ground_truth/sliding").unwrap();
        let params: Value = serde_json::from_str(&channel.metadata["parameters"]).unwrap();
        assert!(params["tuning"].as_str().unwrap().contains("jointly from the"), "{params}");
        assert_eq!(params["r_m2"], joint["r_m2"]);
        assert_eq!(params["gate_reacquire_after"], Value::Null, "the gate re-acquires only when asked");
    }
    let out: Value =
        serde_json::from_str(&ok(&["-q", "label", pa, "--reacquire-after", "3", "--dry-run", "--json"]))
            .unwrap();
    assert_eq!(out[0]["params"]["gate_reacquire_after"], 3);
}

/// With its standard output closed (`slidetrack label ... | head -0`), the
/// command stops with one line, not a panic report and backtrace.
#[test]
fn a_closed_standard_output_stops_with_one_line() {
    let dir = tempdir();
    let file = collect(dir.path(), "box", 8, 2.0, &[]);
    let (reader, writer) = std::io::pipe().unwrap();
    drop(reader);
    let out = common::slidetrack().args(["label", file.to_str().unwrap()]).stdout(writer).output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{stderr}");
    assert!(stderr.contains("standard output was closed"), "{stderr}");
    assert!(!stderr.contains("panicked") && !stderr.contains("backtrace"), "{stderr}");
}

/// A rig whose ground-truth target is a GridBoard (`[marker.board]`): the
/// simulated camera prints it on the box, `collect` records the board's
/// centre pose, and `label` turns it into ground truth as for one marker.
#[test]
fn a_board_on_the_object_gives_ground_truth_like_the_marker() {
    let dir = tempdir();
    let rig = dir.path().join("board-rig.toml");
    std::fs::write(
        &rig,
        "[marker]\ndictionary = \"DICT_6X6_250\"\n[marker.board]\nkind = \"grid\"\nmarkers_x = 2\n\
         markers_y = 3\nmarker_length_m = 0.018\nseparation_m = 0.004\nfirst_id = 20\n",
    )
    .unwrap();
    let file = collect(dir.path(), "box", 3, 8.0, &["--config", rig.to_str().unwrap()]);
    let detections = read_channel::<ArucoDetection>(&file, ReadOptions::default()).unwrap();
    let seen = detections.iter().filter(|(_, d)| d.position_in_camera_m.is_some()).count();
    assert!(seen * 10 >= detections.len() * 9, "{seen} of {} frames with a board pose", detections.len());
    assert!(detections.iter().filter_map(|(_, d)| d.marker_id).all(|id| (20..26).contains(&id)));
    let out: Value = serde_json::from_str(&ok(&["-q", "label", file.to_str().unwrap(), "--json"])).unwrap();
    let rmse_p = out[0]["rmse"]["position_m"].as_f64().unwrap();
    eprintln!("board ground truth vs /sim/truth: {:.3} mm", rmse_p * 1e3);
    assert!(rmse_p <= 0.16e-3, "position RMSE {:.3} mm", rmse_p * 1e3);
}
