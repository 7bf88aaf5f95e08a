//! The reader on the real recordings in `shared/testdata/tactile/xela-imanlab`
//! (read in place) and on corrupted copies of one of them.

use std::fs;
use std::path::{Path, PathBuf};

use super::*;

/// `shared/testdata/tactile/<name>` (the workspace's sibling `shared/`).
fn testdata(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/testdata/tactile").join(name)
}

fn dataset() -> PathBuf {
    testdata("xela-imanlab")
}

/// A sequence with one tactile row more than robot and marker rows.
const WITH_TAIL: &str = "train/data_sample_2021-11-24-15-19-34";

fn all_sequences() -> Vec<XelaSequence> {
    read_sequences(&[dataset().join("train"), dataset().join("test")]).unwrap()
}

#[test]
fn all_53_sequences_parse_and_match_the_summary() {
    let sequences = all_sequences();
    assert_eq!(sequences.len(), 53);
    let summary: serde_json::Value =
        serde_json::from_str(&fs::read_to_string(testdata("xela-imanlab-summary.json")).unwrap()).unwrap();
    let entries = summary["sequences"].as_array().unwrap();
    assert_eq!(entries.len(), 53);
    for entry in entries {
        let dir = entry["dir"].as_str().unwrap();
        let seq = sequences.iter().find(|s| dir.ends_with(&s.name)).unwrap();
        let tactile_rows = seq.frames.len() + seq.tail.tactile[0].len();
        assert_eq!(tactile_rows as u64, entry["n_frames"].as_u64().unwrap(), "{dir}");
        assert_eq!(u64::from(seq.meta.dropped), entry["dropped"].as_u64().unwrap(), "{dir}");
        assert_eq!(seq.meta.object_name, entry["object"].as_str().unwrap(), "{dir}");
        let freq = entry["freq_hz"].as_f64().unwrap();
        assert!((seq.meta.frequency_hz - freq).abs() <= 0.005, "{dir}");
        for (m, key) in ["marker1_valid", "marker2_valid"].iter().enumerate() {
            let seen = seq.frames.iter().filter(|f| f.markers[m].is_some()).count();
            let fraction = seen as f64 / seq.frames.len() as f64;
            assert!((fraction - entry[*key].as_f64().unwrap()).abs() <= 0.0005, "{dir} {key}");
        }
        // The collection script's known artefact: at most one tactile row
        // more than robot and marker rows, in both tactile files alike.
        assert!(seq.tail.robot.is_empty() && seq.tail.markers.is_empty(), "{dir}");
        assert_eq!(seq.tail.tactile[0].len(), seq.tail.tactile[1].len(), "{dir}");
        assert!(seq.tail.tactile[0].len() <= 1, "{dir}");
    }
    let with_tail = sequences.iter().filter(|s| !s.tail.is_empty()).count();
    assert_eq!(with_tail, 16);
}

#[test]
fn frame_times_are_row_index_over_the_recorded_rate() {
    let seq = read_sequence(&dataset().join(WITH_TAIL)).unwrap();
    assert_eq!(seq.frames.len(), 1063);
    assert_eq!(seq.tail.tactile[0].len(), 1);
    for (i, frame) in seq.frames.iter().enumerate() {
        assert_eq!(frame.index, i);
        assert!((frame.t_s - i as f64 / 41.759_140_047_2).abs() < 1e-12);
    }
    // frequency_hz = tactile rows / (stop - start), to a few milliseconds.
    let duration_s = seq.meta.stop_time_s - seq.meta.start_time_s;
    assert!((duration_s - 25.479_522).abs() < 1e-6, "{duration_s}");
    assert!((1064.0 / seq.meta.frequency_hz - duration_s).abs() < 0.01);
}

/// The fields of a CSV file (header excluded), split the simple way: the
/// dataset's files hold no quoted fields.
fn raw_fields(path: &Path) -> Vec<Vec<String>> {
    fs::read_to_string(path)
        .unwrap()
        .lines()
        .skip(1)
        .map(|line| line.split(',').map(str::to_owned).collect())
        .collect()
}

fn number(text: &str) -> f64 {
    text.parse().unwrap()
}

#[test]
fn every_value_of_a_sequence_round_trips() {
    let dir = dataset().join(WITH_TAIL);
    let seq = read_sequence(&dir).unwrap();
    for (s, file) in TACTILE_FILES.iter().enumerate() {
        let raw = raw_fields(&dir.join(file));
        let rows: Vec<&PatchCounts> =
            seq.frames.iter().map(|f| &f.tactile[s]).chain(&seq.tail.tactile[s]).collect();
        assert_eq!(raw.len() * 48, rows.len() * TAXELS * 3, "{file}");
        for (raw_row, patch) in raw.iter().zip(rows) {
            let values: Vec<f64> = patch.iter().flatten().map(|&c| f64::from(c)).collect();
            assert_eq!(raw_row.iter().map(|t| number(t)).collect::<Vec<_>>(), values, "{file}");
        }
    }
    let raw = raw_fields(&dir.join(ROBOT_FILE));
    assert_eq!(raw.len() * 22, seq.frames.len() * 22);
    for (raw_row, frame) in raw.iter().zip(&seq.frames) {
        let r = &frame.robot;
        let values: Vec<f64> = (r.joint_position_rad.iter())
            .chain([&r.finger_position_m])
            .chain(&r.joint_velocity_rad_s)
            .chain(&r.ee_position_in_base_m)
            .chain(&r.ee_orientation_in_base_xyzw)
            .copied()
            .collect();
        assert_eq!(raw_row.iter().map(|t| number(t)).collect::<Vec<_>>(), values);
    }
    let raw = raw_fields(&dir.join(MARKER_FILE));
    assert_eq!(raw.len() * 14, seq.frames.len() * MARKERS * 7);
    for (raw_row, frame) in raw.iter().zip(&seq.frames) {
        let values: Vec<f64> = frame
            .markers
            .iter()
            .flat_map(|m| match m {
                Some(p) => p.position_in_camera_m.into_iter().chain(p.orientation_in_camera_xyzw).collect(),
                None => vec![MARKER_NOT_SEEN; 7],
            })
            .collect();
        assert_eq!(raw_row.iter().map(|t| number(t)).collect::<Vec<_>>(), values);
    }
    let meta = fs::read_to_string(dir.join(META_FILE)).unwrap();
    let mut lines = meta.lines();
    let (header, row) = (lines.next().unwrap().split(','), lines.next().unwrap().split(','));
    let written: Vec<(String, String)> = header.zip(row).map(|(h, v)| (h.to_owned(), v.to_owned())).collect();
    assert_eq!(seq.meta.fields, written);
    assert_eq!((seq.meta.object_name.as_str(), seq.meta.object_class.as_str()), ("7", "box"));
    assert_eq!((seq.meta.seen, seq.meta.dropped, seq.meta.notes.as_deref()), (Some(true), false, None));
    assert_eq!(seq.meta.sensor_type, "xela_2fingers_noglove");
    assert_eq!(
        seq.meta_npy_path.as_deref(),
        Some(
            "/home/user/Robotics/Data_sets/box_only_dataset/train/\
             data_sample_2021-11-24-15-19-34/meta_data.csv"
        )
    );
}

#[test]
fn test_split_meta_has_notes_and_some_folders_have_no_npy() {
    let seq = read_sequence(&dataset().join("test/data_sample_2021-11-25-13-09-52")).unwrap();
    assert_eq!(seq.meta.notes.as_deref(), Some("test motion slow loose grip"));
    assert_eq!(seq.meta.seen, Some(false));
    assert_eq!(seq.meta.fields.len(), 9);
    let seq = read_sequence(&dataset().join("train/data_sample_2021-11-24-15-55-09")).unwrap();
    assert_eq!(seq.meta_npy_path, None);
}

#[test]
fn unseen_markers_are_none_and_seen_ones_are_poses() {
    let sequences = all_sequences();
    let (mut unseen, mut seen) = ([0_usize; MARKERS], [0_usize; MARKERS]);
    for frame in sequences.iter().flat_map(|s| &s.frames) {
        for (m, pose) in frame.markers.iter().enumerate() {
            let Some(pose) = pose else {
                unseen[m] += 1;
                continue;
            };
            seen[m] += 1;
            // A real detection: unit quaternion, in front of the camera, close.
            let norm = pose.orientation_in_camera_xyzw.iter().map(|q| q * q).sum::<f64>().sqrt();
            assert!((norm - 1.0).abs() < 1e-6, "{norm}");
            assert!((0.05..0.6).contains(&pose.position_in_camera_m[2]), "{pose:?}");
        }
    }
    // Counted with awk on the files: rows whose seven fields are all 10.0.
    assert_eq!(unseen, [1931, 23852]);
    assert_eq!(seen[0] + unseen[0], 41332);
}

/// A copy of [`WITH_TAIL`] in a temporary folder, with `edit` applied to one file.
fn corrupted(file: &str, edit: impl FnOnce(String) -> String) -> (tempfile::TempDir, PathBuf) {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("data_sample_corrupted");
    fs::create_dir(&dir).unwrap();
    for entry in fs::read_dir(dataset().join(WITH_TAIL)).unwrap() {
        let path = entry.unwrap().path();
        fs::copy(&path, dir.join(path.file_name().unwrap())).unwrap();
    }
    let text = String::from_utf8_lossy(&fs::read(dir.join(file)).unwrap()).into_owned();
    fs::write(dir.join(file), edit(text)).unwrap();
    (tmp, dir)
}

/// Replaces field `col` (0-based) of CSV line `line` (1-based).
fn set_field(text: &str, line: usize, col: usize, value: &str) -> String {
    let mut lines: Vec<String> = text.lines().map(str::to_owned).collect();
    let mut fields: Vec<&str> = lines[line - 1].split(',').collect();
    fields[col] = value;
    lines[line - 1] = fields.join(",");
    lines.join("\n") + "\n"
}

fn error_of(dir: &Path) -> String {
    let message = format!("{:#}", read_sequence(dir).unwrap_err());
    assert!(!message.contains('\n'), "not one line: {message}");
    message
}

#[test]
fn a_corrupted_value_names_file_line_and_column() {
    let (_tmp, dir) = corrupted("xela_sensor2.csv", |t| set_field(&t, 5, 6, "abc"));
    let message = error_of(&dir);
    assert!(message.contains("xela_sensor2.csv:5: column 7 (txl3_x): not a number: \"abc\""), "{message}");

    let (_tmp, dir) = corrupted("xela_sensor1.csv", |t| set_field(&t, 9, 2, "37638.5"));
    assert!(error_of(&dir).contains("xela_sensor1.csv:9: column 3 (txl1_z): not a whole 16-bit count"));

    let (_tmp, dir) = corrupted("robot_state.csv", |t| set_field(&t, 3, 15, "inf"));
    let message = error_of(&dir);
    assert!(
        message.contains("robot_state.csv:3: column 16 (ee_state_position_x): not a finite"),
        "{message}"
    );

    let (_tmp, dir) = corrupted("meta_data.csv", |t| set_field(&t, 2, 3, "yes"));
    assert!(error_of(&dir).contains("meta_data.csv:2: column 4 (dropped): not a 0/1 flag: \"yes\""));
}

#[test]
fn a_malformed_file_is_a_one_line_error() {
    let (_tmp, dir) = corrupted("marker.csv", |t| {
        let mut lines: Vec<&str> = t.lines().collect();
        lines[6] = "0.1,0.2";
        lines.join("\n")
    });
    let message = error_of(&dir);
    assert!(message.contains("marker.csv:7: expected 14 fields as in the header, found 2"), "{message}");

    let (_tmp, dir) = corrupted("robot_state.csv", |t| t.replacen("position_panda_finger", "gripper", 1));
    let message = error_of(&dir);
    assert!(message.contains("robot_state.csv:1: column 8 is \"gripper\", expected"), "{message}");

    let (_tmp, dir) = corrupted("xela_sensor1.csv", |t| t.lines().next().unwrap().to_owned());
    assert!(error_of(&dir).contains("xela_sensor1.csv: no data rows"));

    let (_tmp, dir) = corrupted("meta_data.csv", |t| t.replace("start_time", "begin"));
    assert!(error_of(&dir).contains("no column \"start_time\""));

    let (_tmp, dir) = corrupted("meta_data.csv.npy", |_| "not numpy".into());
    assert!(error_of(&dir).contains("meta_data.csv.npy: not a NumPy unicode scalar"));
}

#[test]
fn find_sequences_takes_sequence_folders_and_folders_of_them() {
    let one = dataset().join(WITH_TAIL);
    let found = find_sequences(&[dataset().join("test"), one.clone()]).unwrap();
    assert_eq!(found, [dataset().join("test/data_sample_2021-11-25-13-09-52"), one]);
    let train = find_sequences(&[dataset().join("train")]).unwrap();
    assert_eq!(train.len(), 52);
    assert!(train.windows(2).all(|w| w[0] < w[1]));
    let message = format!("{:#}", find_sequences(&[dataset()]).unwrap_err());
    assert!(message.contains("neither a sequence folder nor a folder of sequence folders"), "{message}");
    assert!(find_sequences(&[dataset().join("missing")]).is_err());
}
