//! The reader on the seven real trials in `shared/testdata/tactile/xela-psc`
//! (read in place) and on corrupted copies of one of them; the numbers
//! `docs/real-data.md` ("The xela-psc trials") gives.

use std::fs;
use std::path::{Path, PathBuf};

use nalgebra::{Matrix3, SymmetricEigen, Vector3};

use super::*;
use crate::import::xela_psc_session::SLIDING_AXIS_IN_CAMERA;

/// `shared/testdata/tactile/xela-psc` (the workspace's sibling `shared/`).
fn dataset() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/testdata/tactile/xela-psc")
}

/// The first trial: the longest, no slip.
const FIRST: &str = "data_sample_2022-02-21-09-58-49";

/// One trial's numbers, counted with awk on the files.
struct Trial {
    name: &'static str,
    /// Rows of every file.
    rows: usize,
    /// Rows with `slip` 1.0.
    slip: usize,
    /// Rows with `fail` 1.0.
    fail: usize,
    /// Rows whose marker fields are all 10.0.
    unseen: usize,
    /// The last `time` (s).
    t_last: f64,
    /// `dropped`.
    dropped: bool,
    /// Rows whose counts (both sensors) repeat the previous row's.
    repeated: usize,
}

const fn trial(
    name: &'static str,
    rows: usize,
    labels: [usize; 3],
    t_last: f64,
    dropped: bool,
    repeated: usize,
) -> Trial {
    let [slip, fail, unseen] = labels;
    Trial { name, rows, slip, fail, unseen, t_last, dropped, repeated }
}

/// The seven trials: name, rows, [slip, fail, unseen] rows, last time,
/// dropped, repeated rows.
const TRIALS: [Trial; 7] = [
    trial("data_sample_2022-02-21-09-58-49", 404, [0, 0, 0], 6.75, false, 37),
    trial("data_sample_2022-02-21-14-10-49", 354, [0, 0, 0], 5.917, false, 29),
    trial("data_sample_2022-02-21-15-29-08", 323, [0, 0, 0], 5.387, false, 19),
    trial("data_sample_2022-02-21-17-22-56", 300, [0, 0, 0], 5.02, false, 17),
    trial("data_sample_2022-02-22-08-10-01", 285, [104, 101, 101], 4.751, false, 20),
    trial("data_sample_2022-02-22-11-23-11", 270, [42, 0, 0], 4.501, false, 20),
    trial("data_sample_2022-02-22-15-15-00", 259, [50, 136, 136], 4.314, true, 17),
];

fn all_sequences() -> Vec<PscSequence> {
    read_sequences(&[dataset()]).unwrap()
}

#[test]
fn all_seven_trials_parse_with_the_counted_rows_and_labels() {
    let sequences = all_sequences();
    assert_eq!(sequences.len(), 7);
    for (seq, trial) in sequences.iter().zip(&TRIALS) {
        let Trial { name, rows, slip, fail, unseen, t_last, dropped, repeated } = *trial;
        assert_eq!(seq.name, name);
        assert_eq!(seq.file_rows(), [rows; 5], "{name}");
        assert_eq!((seq.rows(), seq.shared_rows()), (rows, rows), "{name}");
        assert_eq!(seq.labels.iter().filter(|l| l.slip == 1.0).count(), slip, "{name}");
        assert_eq!(seq.labels.iter().filter(|l| l.fail == 1.0).count(), fail, "{name}");
        assert!(seq.labels.iter().all(|l| [0.0, 1.0].contains(&l.slip) && [0.0, 1.0].contains(&l.fail)));
        assert_eq!(seq.markers.iter().filter(|m| m.is_none()).count(), unseen, "{name}");
        // `fail` is exactly "the marker is not seen"; slip and fail never meet.
        for (l, m) in seq.labels.iter().zip(&seq.markers) {
            assert_eq!(l.fail == 1.0, m.is_none(), "{name}");
            assert!(l.slip == 0.0 || l.fail == 0.0, "{name}");
        }
        assert_eq!(seq.meta.dropped, dropped, "{name}");
        let repeats = |s: usize, i: usize| seq.tactile[s][i] == seq.tactile[s][i - 1];
        let both = (1..rows).filter(|&i| repeats(0, i) && repeats(1, i)).count();
        assert_eq!(both, repeated, "{name}");
        // The time column: 0 first, never decreasing, whole milliseconds.
        let t: Vec<f64> = seq.robot.iter().map(|r| r.time_s).collect();
        assert_eq!((t[0], t[rows - 1]), (0.0, t_last), "{name}");
        assert!(t.windows(2).all(|w| w[1] > w[0]), "{name}: a repeated or decreasing time");
        assert!(t.iter().all(|v| (v * 1000.0 - (v * 1000.0).round()).abs() < 1e-6), "{name}");
        assert_eq!(seq.time_s(rows - 1), t_last);
        // frequency_hz is rows over about the time column's span.
        let span_rate = (rows - 1) as f64 / t_last;
        assert!((seq.meta.frequency_hz - span_rate).abs() < 0.2, "{name}: {}", seq.meta.frequency_hz);
        // The wall-clock span is 2.2-3.1 s longer than the time column's.
        let wall = seq.meta.stop_time_s - seq.meta.start_time_s;
        assert!((2.2..3.1).contains(&(wall - t_last)), "{name}: {wall} s");
    }
    let with_slip = sequences.iter().filter(|s| s.labels.iter().any(|l| l.slip != 0.0)).count();
    assert_eq!(with_slip, 3);
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

fn numbers_of(row: &[String]) -> Vec<f64> {
    row.iter().map(|t| t.parse().unwrap()).collect()
}

#[test]
fn every_value_of_every_trial_round_trips() {
    for seq in all_sequences() {
        let dir = dataset().join(&seq.name);
        for (s, file) in TACTILE_FILES.iter().enumerate() {
            let raw = raw_fields(&dir.join(file));
            assert_eq!(raw.len(), seq.tactile[s].len());
            for (row, patch) in raw.iter().zip(&seq.tactile[s]) {
                let values: Vec<f64> = patch.iter().flatten().map(|&c| f64::from(c)).collect();
                assert_eq!(numbers_of(row), values, "{} {file}", seq.name);
            }
        }
        for (row, r) in raw_fields(&dir.join(ROBOT_FILE)).iter().zip(&seq.robot) {
            let values: Vec<f64> = (r.joint_position_rad.iter())
                .chain(&r.joint_velocity_rad_s)
                .chain(&r.ee_transform_column_major)
                .chain([&r.v_x_m_s, &r.v_y_m_s, &r.time_s])
                .copied()
                .collect();
            assert_eq!(numbers_of(row), values, "{}", seq.name);
        }
        for (row, m) in raw_fields(&dir.join(MARKER_FILE)).iter().zip(&seq.markers) {
            let values = match m {
                Some(p) => p.position_in_camera_m.into_iter().chain(p.orientation_in_camera_xyzw).collect(),
                None => vec![MARKER_NOT_SEEN; 7],
            };
            assert_eq!(numbers_of(row), values, "{}", seq.name);
        }
        for (row, l) in raw_fields(&dir.join(LABEL_FILE)).iter().zip(&seq.labels) {
            assert_eq!(numbers_of(row), [l.slip, l.fail], "{}", seq.name);
        }
        let meta = fs::read_to_string(dir.join(META_FILE)).unwrap();
        let mut lines = meta.lines();
        let (header, row) = (lines.next().unwrap().split(','), lines.next().unwrap().split(','));
        let written: Vec<(String, String)> =
            header.zip(row).map(|(h, v)| (h.to_owned(), v.to_owned())).collect();
        assert_eq!(seq.meta.fields, written);
        assert_eq!((seq.meta.notes.as_str(), seq.meta.sensor_type.as_str()), ("0", "xela_2fingers_glove"));
    }
}

#[test]
fn first_and_last_values_match_the_csv_text() {
    let seq = read_sequence(&dataset().join(FIRST)).unwrap();
    assert_eq!(seq.tactile[0][0][0], [16080, 16547, 39017]);
    assert_eq!(seq.tactile[0][403][15], [15657, 16446, 39383]);
    assert_eq!(seq.tactile[1][0][15], [15492, 16026, 39062]);
    let first = seq.markers[0].unwrap();
    assert_eq!(first.position_in_camera_m, [0.0293840840459, -0.0280921757221, 0.175283938646]);
    assert_eq!(first.orientation_in_camera_xyzw[3], -0.270349373496);
    let last = seq.markers[403].unwrap();
    assert_eq!(last.position_in_camera_m[2], 0.176377132535);
    let r = &seq.robot[1];
    assert_eq!(r.joint_position_rad[0], 0.465059457361);
    assert_eq!((r.v_x_m_s, r.v_y_m_s, r.time_s), (-0.00018, -0.000236571428571, 0.01));
    assert_eq!(seq.robot[403].ee_position_in_base_m(), [0.216941435024, -0.323058822001, 0.304959266798]);
    assert_eq!(seq.meta.frequency_hz, 59.7544117);
    assert!((seq.meta.stop_time_s - seq.meta.start_time_s - 8.953459).abs() < 1e-6);
    let seq = read_sequence(&dataset().join("data_sample_2022-02-22-15-15-00")).unwrap();
    assert!(seq.meta.dropped);
    assert!(seq.markers[258].is_none() && seq.labels[258] == SlipLabel { slip: 0.0, fail: 1.0 });
    assert_eq!(seq.labels[73].slip, 1.0);
}

#[test]
fn the_transform_is_column_major_and_its_rotation_a_quaternion() {
    for seq in all_sequences() {
        for r in &seq.robot {
            let t = r.ee_transform();
            // Column-major: the last row is 0 0 0 1, the translation column 3.
            assert_eq!(t.row(3).iter().copied().collect::<Vec<_>>(), [0.0, 0.0, 0.0, 1.0]);
            assert_eq!([t[(0, 3)], t[(1, 3)], t[(2, 3)]], r.ee_position_in_base_m());
            let block = Matrix3::from(t.fixed_view::<3, 3>(0, 0));
            let [x, y, z, w] = r.ee_orientation_in_base_xyzw();
            let norm = (x * x + y * y + z * z + w * w).sqrt();
            assert!(w >= 0.0 && (norm - 1.0).abs() < 1e-12, "{}: {x} {y} {z} {w}", seq.name);
            let q = nalgebra::UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(w, x, y, z));
            let off = (q.to_rotation_matrix().matrix() - block).abs().max();
            assert!(off < 1e-4, "{}: {off}", seq.name);
        }
    }
}

#[test]
fn v_x_and_v_y_are_the_base_frame_velocity_on_a_fixed_line() {
    for seq in all_sequences() {
        let mut error = 0.0;
        for w in seq.robot.windows(2) {
            let (a, b) = (w[0].ee_position_in_base_m(), w[1].ee_position_in_base_m());
            let dt = w[1].time_s - w[0].time_s;
            error += ((b[0] - a[0]) / dt - w[1].v_x_m_s).abs() + ((b[1] - a[1]) / dt - w[1].v_y_m_s).abs();
            if w[1].v_x_m_s != 0.0 {
                let ratio = w[1].v_y_m_s / w[1].v_x_m_s;
                assert!((ratio - 0.46 / 0.35).abs() < 1e-9, "{}: {ratio}", seq.name);
            }
        }
        let mean = error / (2.0 * (seq.robot.len() - 1) as f64);
        assert!(mean < 0.004, "{}: mean |finite difference - v| = {mean} m/s", seq.name);
        // The first second is the command ramp v_x = -0.02 t of the authors'
        // controller, one 1 ms tick late: the command in force at the row.
        for r in seq.robot.iter().filter(|r| r.time_s > 0.0 && r.time_s < 0.99) {
            assert!((r.v_x_m_s + 0.02 * (r.time_s - 0.001)).abs() < 1e-12, "{}: {r:?}", seq.name);
        }
    }
}

/// The principal direction of points and its share of the variance.
fn principal_axis(points: &[Vector3<f64>]) -> (Vector3<f64>, f64) {
    let mu = points.iter().sum::<Vector3<f64>>() / points.len() as f64;
    let cov = points.iter().map(|p| (p - mu) * (p - mu).transpose()).sum::<Matrix3<f64>>();
    let eig = SymmetricEigen::new(cov);
    let i = eig.eigenvalues.imax();
    (eig.eigenvectors.column(i).into_owned(), eig.eigenvalues[i] / eig.eigenvalues.sum())
}

#[test]
fn the_sliding_axis_is_the_pooled_principal_direction_of_the_marker() {
    let mut pooled = Vec::new();
    for seq in all_sequences() {
        let track: Vec<Vector3<f64>> =
            seq.markers.iter().flatten().map(|m| Vector3::from(m.position_in_camera_m)).collect();
        pooled.extend(track.iter().map(|p| p - track[0]));
    }
    let (mut axis, explained) = principal_axis(&pooled);
    if axis.dot(&pooled.iter().sum::<Vector3<f64>>()) < 0.0 {
        axis = -axis;
    }
    let constant = Vector3::from(SLIDING_AXIS_IN_CAMERA).normalize();
    let degrees = constant.dot(&axis).clamp(-1.0, 1.0).acos().to_degrees();
    assert!(degrees < 1.0, "axis {axis:?} ({:.0} % explained), {degrees} degrees off", 100.0 * explained);
    assert!(explained > 0.95, "{explained}");
}

/// A copy of [`FIRST`] in a temporary folder, with `edit` applied to one file.
fn corrupted(file: &str, edit: impl FnOnce(String) -> String) -> (tempfile::TempDir, PathBuf) {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("data_sample_corrupted");
    fs::create_dir(&dir).unwrap();
    for entry in fs::read_dir(dataset().join(FIRST)).unwrap() {
        let path = entry.unwrap().path();
        fs::copy(&path, dir.join(path.file_name().unwrap())).unwrap();
    }
    let text = fs::read_to_string(dir.join(file)).unwrap();
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

    let (_tmp, dir) = corrupted("robot_state.csv", |t| set_field(&t, 3, 30, "nan"));
    let message = error_of(&dir);
    assert!(message.contains("robot_state.csv:3: column 31 (v_x): not a finite number"), "{message}");

    let (_tmp, dir) = corrupted("slip_label.csv", |t| set_field(&t, 7, 0, "yes"));
    let message = error_of(&dir);
    assert!(message.contains("slip_label.csv:7: column 1 (slip): not a number: \"yes\""), "{message}");

    let (_tmp, dir) = corrupted("meta_data.csv", |t| set_field(&t, 2, 0, "2"));
    assert!(error_of(&dir).contains("meta_data.csv:2: column 1 (dropped): not a 0/1 flag: \"2\""));

    let (_tmp, dir) = corrupted("robot_state.csv", |t| set_field(&t, 10, 32, "0.05"));
    let message = error_of(&dir);
    assert!(
        message.contains(
            "robot_state.csv:10: column 33 (time): time goes back (previous row 0.107 s): \"0.05\""
        ),
        "{message}"
    );
}

#[test]
fn a_malformed_file_is_a_one_line_error_naming_it() {
    let (_tmp, dir) = corrupted("marker.csv", |t| {
        let mut lines: Vec<&str> = t.lines().collect();
        lines[6] = "0.1,0.2";
        lines.join("\n")
    });
    let message = error_of(&dir);
    assert!(message.contains("marker.csv:7: expected 7 fields as in the header, found 2"), "{message}");

    let (_tmp, dir) = corrupted("robot_state.csv", |t| t.replacen("ee_T_10,ee_T_20", "ee_T_01,ee_T_02", 1));
    let message = error_of(&dir);
    assert!(
        message.contains("robot_state.csv:1: column 16 is \"ee_T_01\", expected \"ee_T_10\""),
        "{message}"
    );

    let (_tmp, dir) = corrupted("slip_label.csv", |t| t.replacen("slip,fail", "slip,failed", 1));
    let message = error_of(&dir);
    assert!(message.contains("slip_label.csv:1: column 2 is \"failed\", expected \"fail\""), "{message}");

    let (_tmp, dir) = corrupted("xela_sensor1.csv", |t| t.lines().next().unwrap().to_owned());
    assert!(error_of(&dir).contains("xela_sensor1.csv: no data rows"));

    let (_tmp, dir) = corrupted("meta_data.csv", |t| t.replace("notes", "comment"));
    let message = error_of(&dir);
    assert!(message.contains("meta_data.csv:1: column 2 is \"comment\", expected \"notes\""), "{message}");

    let (_tmp, dir) = corrupted("meta_data.csv", |t| t.clone() + t.lines().nth(1).unwrap() + "\n");
    assert!(error_of(&dir).contains("meta_data.csv: expected one data row, found 2"));

    let (_tmp, dir) = corrupted("slip_label.csv", |t| t);
    fs::remove_file(dir.join("slip_label.csv")).unwrap();
    let message = error_of(&dir);
    assert!(message.contains("slip_label.csv: cannot open"), "{message}");
}

#[test]
fn a_file_with_more_rows_keeps_them_and_its_times_follow_the_rate() {
    // Three robot rows fewer than the other files: the extra rows are kept
    // and timed at 1 / frequency_hz after the last robot row.
    let (_tmp, dir) = corrupted("robot_state.csv", |t| {
        let lines: Vec<&str> = t.lines().collect();
        lines[..lines.len() - 3].join("\n") + "\n"
    });
    let seq = read_sequence(&dir).unwrap();
    assert_eq!(seq.file_rows(), [404, 404, 404, 401, 404]);
    assert_eq!((seq.rows(), seq.shared_rows()), (404, 401));
    let last = seq.robot[400].time_s;
    assert!((seq.time_s(403) - (last + 3.0 / seq.meta.frequency_hz)).abs() < 1e-12);
}

#[test]
fn find_sequences_takes_the_dataset_folder_or_trial_folders() {
    let one = dataset().join(FIRST);
    assert_eq!(find_sequences(std::slice::from_ref(&one)).unwrap(), [one]);
    let all = find_sequences(&[dataset()]).unwrap();
    assert_eq!(all.len(), 7);
    assert!(all.windows(2).all(|w| w[0] < w[1]));
}
