//! `slidetrack vision track --live`: the live path end to end on a recorded
//! stand-in for the RGB-D camera (a simulated session replayed in real time,
//! or frame by frame, as two unsynchronised cameras, paired and registered),
//! recording frames and estimates; bad rigs fail with one line.

#![expect(clippy::unwrap_used, reason = "test code: a failed unwrap is a failed test")]

mod common;

use std::collections::BTreeMap;
use std::path::Path;

use common::{fails, ok, tempdir};
use serde_json::Value;
use slidetrack_estimators::metrics::{perturbed_start, position_error_m, rotation_error_deg};
use slidetrack_session::{ObjectTruth, PoseInFrame, ReadOptions, SessionInfo, read_json};

/// A rig whose `[rgbd]` camera replays `session` at `pace`: colour 5 ms
/// after depth, depth registered with identity extrinsics.
fn rig(dir: &Path, session: &Path, pace: &str) -> String {
    let rig = dir.join(format!("rig-{pace}.toml"));
    let text = format!(
        "[rgbd]\nkind = \"recording\"\nsession = \"{}\"\ncolor_delay_ms = 5.0\npace = \"{pace}\"\n\
         [rgbd.depth_to_color]\nrotation_row_major = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]\n\
         translation_m = [0.0, 0.0, 0.0]\n",
        session.file_name().unwrap().to_str().unwrap()
    );
    std::fs::write(&rig, text).unwrap();
    rig.to_str().unwrap().to_string()
}

/// Mean position (cm) and rotation (deg) errors of `poses` against the truth
/// logged at the same times.
fn mean_errors<'a>(
    poses: impl Iterator<Item = (u64, &'a nalgebra::Isometry3<f64>)>,
    truth: &BTreeMap<u64, nalgebra::Isometry3<f64>>,
) -> (f64, f64) {
    let errors: Vec<(f64, f64)> = poses
        .map(|(t, pose)| {
            let truth = truth.get(&t).unwrap_or_else(|| panic!("no truth logged at {t} ns"));
            (position_error_m(pose, truth) * 100.0, rotation_error_deg(pose, truth))
        })
        .collect();
    let n = errors.len() as f64;
    (errors.iter().map(|e| e.0).sum::<f64>() / n, errors.iter().map(|e| e.1).sum::<f64>() / n)
}

/// Mean errors over the second half of the run, of the estimates of
/// `tracker` recorded in `out` and of a tracker frozen at its start (the
/// perturbed first true pose): `((cm, deg), (cm, deg))`.
fn second_half_errors(out: &Path, tracker: &str) -> ((f64, f64), (f64, f64)) {
    let truth: BTreeMap<u64, _> = read_json::<ObjectTruth>(out, "/sim/object", ReadOptions::default())
        .unwrap()
        .into_iter()
        .map(|(t, o)| (t.0, o.to_sim(t).unwrap().camera_from_object))
        .collect();
    let poses: Vec<(u64, _)> =
        read_json::<PoseInFrame>(out, &format!("/estimate/pose/{tracker}"), ReadOptions::default())
            .unwrap()
            .into_iter()
            .map(|(t, p)| (t.0, p.pose.to_isometry().unwrap()))
            .collect();
    let second_half = &poses[poses.len() / 2..];
    let (tracked_cm, tracked_deg) = mean_errors(second_half.iter().map(|(t, p)| (*t, p)), &truth);
    // A frozen tracker stays where it started: the perturbed first true pose.
    let first_truth = truth.values().next().unwrap();
    let frozen = perturbed_start(first_truth);
    let (frozen_cm, frozen_deg) = mean_errors(second_half.iter().map(|(t, _)| (*t, &frozen)), &truth);
    ((tracked_cm, tracked_deg), (frozen_cm, frozen_deg))
}

/// `vision track --live` with MaskUKF, the true masks of the recording and
/// `--init perturbed` (8.7 cm, 19 degrees off) on a 5 s replay of a moving
/// object (0.15 m/s, 45 deg/s peak), at `pace`: runs `--out`'s session with
/// the frames, their truth and the estimates; returns the summary and the
/// session.
fn live_maskukf(dir: &Path, pace: &str) -> (Value, std::path::PathBuf) {
    let session = dir.join("moving.mcap");
    if !session.exists() {
        let s = session.to_str().unwrap();
        let simulate =
            ["-q", "vision", "simulate", "--object", "sugar_box", "--duration", "5", "--seed", "4"];
        ok(&[&simulate[..], &["--max-speed", "0.15", "--max-angular-speed", "45", "--out", s]].concat());
    }
    let rig = rig(dir, &session, pace);
    let out = dir.join(format!("live-{pace}.mcap"));
    let o = out.to_str().unwrap();
    let tracker =
        ["--tracker", "maskukf", "--model", "sim", "--measurements", "truth", "--init", "perturbed"];
    let args =
        [&["-q", "vision", "track", "--live", "--rig", &rig][..], &tracker[..], &["--out", o, "--json"]];
    let summary: Value = serde_json::from_str(&ok(&args.concat())).unwrap();
    println!("live maskukf on the replay at {pace} pace: {summary}");
    (summary, out)
}

/// In real time the replay runs its 5 s and the frames the tracker took are
/// recorded with their truth and estimates, the rest counted as skipped or
/// lost: a loaded machine may process only a few (CI once processed 2 of
/// 150), so accuracy is asserted frame by frame, below.
#[test]
fn maskukf_runs_live_in_real_time_and_records_the_frames_it_took() {
    let dir = tempdir();
    let (summary, out) = live_maskukf(dir.path(), "realtime");
    let frames = summary["frames"].as_u64().unwrap();
    let tracked = summary["tracked"].as_u64().unwrap();
    assert!(frames >= 1 && tracked == frames, "{summary}");
    assert!(summary["seconds"].as_f64().unwrap() > 4.8, "{summary}");
    let pairing = &summary["pairing"];
    assert_eq!(pairing["pairs"].as_u64(), Some(frames));
    // Every depth frame of the 150 was delivered and paired, or lost while
    // the tracker was behind.
    let depth_lost: u64 = summary["streams"][1]
        .as_str()
        .and_then(|l| l.split(", ").nth(1)?.split(' ').next()?.parse().ok())
        .unwrap();
    let paired_or_skipped = pairing["pairs"].as_u64().unwrap() + pairing["skipped_pairs"].as_u64().unwrap();
    assert_eq!(
        paired_or_skipped + pairing["unpaired_depth"].as_u64().unwrap() + depth_lost,
        150,
        "{summary}"
    );

    let info = SessionInfo::read(&out, ReadOptions::default()).unwrap();
    for topic in ["/rgbd/color", "/rgbd/depth", "/sim/object"] {
        assert_eq!(info.channel(topic).map(|c| c.message_count), Some(frames), "{topic}");
    }
    assert_eq!(info.channel("/rgbd/calibration").map(|c| c.message_count), Some(1));
    for topic in ["/estimate/pose/maskukf", "/estimate/transform/maskukf", "/estimate/velocity/maskukf"] {
        assert_eq!(info.channel(topic).map(|c| c.message_count), Some(tracked), "{topic}");
    }
}

/// Frame by frame (`pace = "every-frame"`) MaskUKF gets all 150 frames on
/// any machine, and over the second half of the run its estimates are far
/// closer to the truth than a tracker frozen at its start, in position and
/// in rotation.
#[test]
fn maskukf_tracks_live_frame_by_frame_from_the_perturbed_start() {
    let dir = tempdir();
    let (summary, out) = live_maskukf(dir.path(), "every-frame");
    assert_eq!(
        (summary["frames"].as_u64(), summary["tracked"].as_u64()),
        (Some(150), Some(150)),
        "{summary}"
    );
    let ((tracked_cm, tracked_deg), (frozen_cm, frozen_deg)) = second_half_errors(&out, "maskukf");
    println!(
        "second half: tracked {tracked_cm:.2} cm, {tracked_deg:.1} deg; frozen at the start {frozen_cm:.2} cm, {frozen_deg:.1} deg"
    );
    // Measured: 0.56 cm, 5.8 deg against 8.55 cm, 31.5 deg frozen.
    assert!(
        tracked_cm < 2.0 && tracked_cm < frozen_cm / 4.0,
        "{tracked_cm:.2} cm vs frozen {frozen_cm:.2} cm"
    );
    assert!(tracked_deg < frozen_deg / 2.0, "{tracked_deg:.1} deg vs frozen {frozen_deg:.1} deg");
}

/// The live path with the pose source that needs no network: a replayed
/// session whose object carries an ArUco marker (`vision simulate
/// --marker`), ROFT and MaskUKF fed the marker's 6D pose and the masks
/// rendered at it, from the perturbed start. The replay hands over every
/// frame (`pace = "every-frame"`), so a loaded machine tracks the same 90
/// frames as an idle one. The frames and the estimates are recorded, the
/// marker is found, and over the second half each tracker is far closer to
/// the truth than one frozen at its start, in position and in rotation.
#[test]
fn the_live_path_tracks_with_the_marker_derived_poses_and_masks() {
    let dir = tempdir();
    let session = dir.path().join("marker.mcap");
    let s = session.to_str().unwrap();
    let simulate = ["-q", "vision", "simulate", "--duration", "3", "--seed", "2", "--max-speed", "0.2"];
    let marker = ["--max-angular-speed", "45", "--marker", "DICT_4X4_50:0", "--marker-size", "0.04"];
    ok(&[&simulate[..], &marker[..], &["--out", s]].concat());
    let config = dir.path().join("marker.aruco.toml");
    let rig = rig(dir.path(), &session, "every-frame");
    for tracker in ["roft", "maskukf"] {
        let out = dir.path().join(format!("live-{tracker}.mcap"));
        let args = [
            "-q",
            "vision",
            "track",
            "--live",
            "--rig",
            &rig,
            "--tracker",
            tracker,
            "--model",
            "sim",
            "--measurements",
            "aruco",
            "--aruco-config",
            config.to_str().unwrap(),
            "--init",
            "perturbed",
            "--out",
            out.to_str().unwrap(),
            "--json",
        ];
        let run = common::run(&args);
        let stderr = String::from_utf8_lossy(&run.stderr);
        assert!(run.status.success(), "{stderr}");
        let summary: Value = serde_json::from_str(&String::from_utf8_lossy(&run.stdout)).unwrap();
        let frames = summary["frames"].as_u64().unwrap();
        assert!(frames == 90 && summary["tracked"].as_u64() == Some(frames), "{summary}");
        assert!(stderr.contains("aruco: ") && !stderr.contains(" 0 poses"), "{stderr}");
        let info = SessionInfo::read(&out, ReadOptions::default()).unwrap();
        assert_eq!(info.channel("/rgbd/color").map(|c| c.message_count), Some(frames));
        let estimates = format!("/estimate/pose/{tracker}");
        assert_eq!(info.channel(&estimates).map(|c| c.message_count), Some(frames), "{estimates}");
        let ((tracked_cm, tracked_deg), (frozen_cm, frozen_deg)) = second_half_errors(&out, tracker);
        println!(
            "{tracker} live with ArUco poses, {frames} frames: tracked {tracked_cm:.2} cm, {tracked_deg:.1} deg; \
             frozen {frozen_cm:.2} cm, {frozen_deg:.1} deg"
        );
        // Measured: ROFT 0.52 cm, 1.8 deg; MaskUKF 0.33 cm, 5.4 deg (frozen
        // 9.0 cm, 23 deg). Before the replay handed over every frame, a
        // loaded CI machine processed 29 of the 90 and MaskUKF's rotation
        // stayed at 22 deg.
        assert!(
            tracked_cm < 2.0 && tracked_cm < frozen_cm / 4.0,
            "{tracker}: {tracked_cm:.2} cm vs frozen {frozen_cm:.2} cm"
        );
        assert!(
            tracked_deg < frozen_deg / 2.0,
            "{tracker}: {tracked_deg:.1} deg vs frozen {frozen_deg:.1} deg"
        );
    }
}

#[test]
fn bad_rigs_fail_with_one_line() {
    let dir = tempdir();
    let no_rgbd = dir.path().join("no-rgbd.toml");
    std::fs::write(&no_rgbd, "[marker]\nid = 3\n").unwrap();
    let base = ["vision", "track", "--tracker", "roft", "--model", "sugar_box", "--live", "--rig"];
    let line = fails(&[&base[..], &[no_rgbd.to_str().unwrap()]].concat());
    assert!(line.contains("no-rgbd.toml") && line.contains("no [rgbd] table"), "{line}");

    let missing = dir.path().join("missing.toml");
    std::fs::write(&missing, "[rgbd]\nkind = \"recording\"\nsession = \"nothing.mcap\"\n").unwrap();
    let line = fails(&[&base[..], &[missing.to_str().unwrap()]].concat());
    assert!(line.contains("rgbd.session") && line.contains("nothing.mcap"), "{line}");

    let bad_depth = dir.path().join("bad-depth.toml");
    std::fs::write(&bad_depth, "[rgbd]\nkind = \"v4l2\"\n[rgbd.depth]\npixel_format = \"YUYV\"\n").unwrap();
    let line = fails(&[&base[..], &[bad_depth.to_str().unwrap()]].concat());
    assert!(line.contains("rgbd.color") || line.contains("rgbd.depth"), "{line}");
}
