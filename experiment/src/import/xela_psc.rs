//! Reader of the xela-psc recordings (imanlab's `proactive-slip-control`
//! `data_set/`, Nazari, Mandil and Ghalamzan E, CoRL 2022): a Franka Panda
//! whose two fingers carry XELA uSkin 4x4 patches moves a grasped box along
//! a line in the base's xy plane under Cartesian velocity control, faster
//! from trial to trial until it slips; one ArUco marker on the box is seen
//! by a camera on the wrist.
//!
//! One trial is a folder (`data_sample_<date>`) of six CSV files written by
//! pandas, one row per ROS `ApproximateTimeSynchronizer` callback (~60 Hz):
//! `xela_sensor1.csv`, `xela_sensor2.csv` (48 raw counts each, the columns
//! of xela-imanlab), `marker.csv` (one pose, 7 columns, 10.0 everywhere when
//! not seen), `robot_state.csv` (33 columns: joints, joint velocities, the
//! 4x4 end-effector transform column-major, the velocity command `v_x`,
//! `v_y`, and the controller's `time`), `slip_label.csv` (`slip`, `fail`,
//! made by the dataset's authors) and `meta_data.csv` (one row).
//! `docs/real-data.md` ("The xela-psc trials") tells what the columns mean
//! and how that was established.
//!
//! [`read_sequence`] keeps every value of every file, each file's rows in
//! their own list (all files of the seven published trials have the same
//! number of rows; a file with more rows than another keeps them). Headers
//! must be exactly the dataset's; the `time` column must not decrease; a
//! malformed file is an error naming file, line and column.

#[cfg(test)]
mod tests;

use std::path::Path;

use anyhow::{Context, Result, bail};
use nalgebra::{Matrix3, Matrix4, Rotation3, UnitQuaternion};

use super::csv_parse::{At, numbers, parse_f64, parse_flag, parse_wall_time_s, read_rows, read_table};
pub use super::xela_csv::find_sequences;
pub use super::xela_csv::{MARKER_FILE, MARKER_NOT_SEEN, META_FILE, ROBOT_FILE, TACTILE_FILES};
use super::xela_csv::{MarkerPose, PatchCounts, SENSORS, read_tactile};

/// The slip label file.
pub const LABEL_FILE: &str = "slip_label.csv";

/// Columns of `robot_state.csv`, in order.
pub const ROBOT_COLUMNS: [&str; 33] = [
    "position_joint1",
    "position_joint2",
    "position_joint3",
    "position_joint4",
    "position_joint5",
    "position_joint6",
    "position_joint7",
    "velocity_joint1",
    "velocity_joint2",
    "velocity_joint3",
    "velocity_joint4",
    "velocity_joint5",
    "velocity_joint6",
    "velocity_joint7",
    "ee_T_00",
    "ee_T_10",
    "ee_T_20",
    "ee_T_30",
    "ee_T_01",
    "ee_T_11",
    "ee_T_21",
    "ee_T_31",
    "ee_T_02",
    "ee_T_12",
    "ee_T_22",
    "ee_T_32",
    "ee_T_03",
    "ee_T_13",
    "ee_T_23",
    "ee_T_33",
    "v_x",
    "v_y",
    "time",
];

/// Columns of `marker.csv`, in order.
pub const MARKER_COLUMNS: [&str; 7] = [
    "marker_position_x",
    "marker_position_y",
    "marker_position_z",
    "marker_quaternion_x",
    "marker_quaternion_y",
    "marker_quaternion_z",
    "marker_quaternion_w",
];

/// Columns of `slip_label.csv`.
pub const LABEL_COLUMNS: [&str; 2] = ["slip", "fail"];

/// Columns of `meta_data.csv`, in order.
pub const META_COLUMNS: [&str; 6] =
    ["dropped", "notes", "sensor_type", "frequency_hz", "start_time", "stop_time"];

/// Index of the `time` column in `robot_state.csv`.
const TIME_COLUMN: usize = 32;

/// One trial folder, every value of every file; each file's rows in file
/// order (row `i` is CSV line `i + 2`).
#[derive(Clone, Debug, PartialEq)]
pub struct PscSequence {
    /// The folder name (`data_sample_2022-02-21-09-58-49`).
    pub name: String,
    /// `meta_data.csv`.
    pub meta: PscMeta,
    /// `xela_sensor1.csv` and `xela_sensor2.csv`.
    pub tactile: [Vec<PatchCounts>; SENSORS],
    /// `marker.csv`; `None` where all seven fields are 10.0 (not seen).
    pub markers: Vec<Option<MarkerPose>>,
    /// `robot_state.csv`.
    pub robot: Vec<PscRobotState>,
    /// `slip_label.csv`.
    pub labels: Vec<SlipLabel>,
}

/// `meta_data.csv`: one row of named values.
#[derive(Clone, Debug, PartialEq)]
pub struct PscMeta {
    /// `dropped` (0/1), as the authors typed it after the trial.
    pub dropped: bool,
    /// `notes` (free text; `0` in every published trial).
    pub notes: String,
    /// `sensor_type` (`xela_2fingers_glove`).
    pub sensor_type: String,
    /// `frequency_hz`: tactile rows over the time from the first
    /// synchronised row to the end of the recording (Hz), as the collection
    /// script computed it.
    pub frequency_hz: f64,
    /// `start_time`: wall clock of the recording PC when the subscription
    /// started, before the arm moved (s since 1970-01-01 of that clock; no
    /// time zone was written).
    pub start_time_s: f64,
    /// `stop_time`: wall clock when the recording stopped (s, same clock).
    pub stop_time_s: f64,
    /// Every column as written, in file order.
    pub fields: Vec<(String, String)>,
}

/// `robot_state.csv`, one row (Franka Panda; base frame `O` of libfranka).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PscRobotState {
    /// `position_joint1..7` (rad).
    pub joint_position_rad: [f64; 7],
    /// `velocity_joint1..7` (rad/s).
    pub joint_velocity_rad_s: [f64; 7],
    /// `ee_T_00, ee_T_10, ee_T_20, ee_T_30, ee_T_01, ..., ee_T_33` as written:
    /// the base-from-end-effector transform column-major (element
    /// `ee_T_<row><col>`; libfranka's `O_T_EE`).
    pub ee_transform_column_major: [f64; 16],
    /// `v_x`: the Cartesian velocity command along the base x axis (m/s).
    pub v_x_m_s: f64,
    /// `v_y`: the Cartesian velocity command along the base y axis (m/s).
    pub v_y_m_s: f64,
    /// `time`: the controller's clock (s; 0 at the first row, 1 ms steps).
    pub time_s: f64,
}

impl PscRobotState {
    fn from_values(v: &[f64; 33]) -> PscRobotState {
        PscRobotState {
            joint_position_rad: std::array::from_fn(|i| v[i]),
            joint_velocity_rad_s: std::array::from_fn(|i| v[7 + i]),
            ee_transform_column_major: std::array::from_fn(|i| v[14 + i]),
            v_x_m_s: v[30],
            v_y_m_s: v[31],
            time_s: v[TIME_COLUMN],
        }
    }

    /// The base-from-end-effector transform.
    pub fn ee_transform(&self) -> Matrix4<f64> {
        Matrix4::from_column_slice(&self.ee_transform_column_major)
    }

    /// End-effector position in the base frame (m): `ee_T_03, ee_T_13, ee_T_23`.
    pub fn ee_position_in_base_m(&self) -> [f64; 3] {
        let t = &self.ee_transform_column_major;
        [t[12], t[13], t[14]]
    }

    /// Base-from-end-effector rotation (x, y, z, w): the rotation nearest the
    /// transform's 3x3 block, w >= 0.
    pub fn ee_orientation_in_base_xyzw(&self) -> [f64; 4] {
        let m = self.ee_transform();
        nearest_rotation_xyzw(&Matrix3::from(m.fixed_view::<3, 3>(0, 0)))
    }
}

/// The unit quaternion (x, y, z, w) of the rotation nearest `m`, with w >= 0.
pub(crate) fn nearest_rotation_xyzw(m: &Matrix3<f64>) -> [f64; 4] {
    // Shepperd's method on the block as is (not quite a unit quaternion, as
    // the block is not quite a rotation), normalised, refined to the nearest
    // rotation.
    let shepperd = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(*m));
    let guess = UnitQuaternion::new_normalize(shepperd.into_inner());
    let q = UnitQuaternion::new_normalize(UnitQuaternion::from_matrix_eps(m, 1e-12, 100, guess).into_inner());
    let c = q.coords;
    let sign = if c.w < 0.0 { -1.0 } else { 1.0 };
    [sign * c.x, sign * c.y, sign * c.z, sign * c.w]
}

/// `slip_label.csv`, one row, the values as written (0.0 or 1.0 in the
/// published trials).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SlipLabel {
    /// `slip`: the authors' slip label of the row.
    pub slip: f64,
    /// `fail`: the authors' failure label (1.0 exactly on the rows where the
    /// marker is not seen, in the published trials).
    pub fail: f64,
}

impl PscSequence {
    /// Rows of the longest file.
    pub fn rows(&self) -> usize {
        self.file_rows().into_iter().max().unwrap_or(0)
    }

    /// Rows every file has.
    pub fn shared_rows(&self) -> usize {
        self.file_rows().into_iter().min().unwrap_or(0)
    }

    /// Rows of `xela_sensor1.csv`, `xela_sensor2.csv`, `marker.csv`,
    /// `robot_state.csv`, `slip_label.csv`.
    pub fn file_rows(&self) -> [usize; 5] {
        let [a, b] = &self.tactile;
        [a.len(), b.len(), self.markers.len(), self.robot.len(), self.labels.len()]
    }

    /// Time of row `i` (s): `robot_state.csv`'s `time`; rows beyond the last
    /// robot row follow it at `1 / frequency_hz` each.
    pub fn time_s(&self, i: usize) -> f64 {
        match (self.robot.get(i), self.robot.last()) {
            (Some(r), _) => r.time_s,
            (None, Some(last)) => last.time_s + (i + 1 - self.robot.len()) as f64 / self.meta.frequency_hz,
            (None, None) => i as f64 / self.meta.frequency_hz,
        }
    }
}

/// Reads one trial folder.
pub fn read_sequence(dir: &Path) -> Result<PscSequence> {
    let name = dir
        .file_name()
        .and_then(|n| n.to_str())
        .with_context(|| format!("{}: not a folder name", dir.display()))?
        .to_owned();
    let meta = read_meta(&dir.join(META_FILE))?;
    let [t1, t2] = TACTILE_FILES.map(|f| dir.join(f));
    let tactile = [read_tactile(&t1)?, read_tactile(&t2)?];
    let markers = read_markers(&dir.join(MARKER_FILE))?;
    let robot = read_robot(&dir.join(ROBOT_FILE))?;
    let labels = read_labels(&dir.join(LABEL_FILE))?;
    Ok(PscSequence { name, meta, tactile, markers, robot, labels })
}

/// Reads every trial [`find_sequences`] finds in `dirs`.
pub fn read_sequences(dirs: &[std::path::PathBuf]) -> Result<Vec<PscSequence>> {
    find_sequences(dirs)?.iter().map(|dir| read_sequence(dir)).collect()
}

fn read_markers(path: &Path) -> Result<Vec<Option<MarkerPose>>> {
    read_rows(path, &MARKER_COLUMNS, |path, header, row| {
        Ok(MarkerPose::from_values(&numbers::<7>(path, header, row)?))
    })
}

/// `robot_state.csv`; the `time` column must be >= 0 and never decrease.
fn read_robot(path: &Path) -> Result<Vec<PscRobotState>> {
    let mut previous: Option<f64> = None;
    read_rows(path, &ROBOT_COLUMNS, |path, header, row| {
        let state = PscRobotState::from_values(&numbers::<33>(path, header, row)?);
        let at = At { path, line: row.line, col: TIME_COLUMN, name: ROBOT_COLUMNS[TIME_COLUMN] };
        let t = state.time_s;
        if t < 0.0 {
            return Err(at.error("negative time", &row.fields[TIME_COLUMN]));
        }
        if let Some(p) = previous.filter(|&p| t < p) {
            return Err(at.error(&format!("time goes back (previous row {p} s)"), &row.fields[TIME_COLUMN]));
        }
        previous = Some(t);
        Ok(state)
    })
}

fn read_labels(path: &Path) -> Result<Vec<SlipLabel>> {
    read_rows(path, &LABEL_COLUMNS, |path, header, row| {
        let [slip, fail] = numbers::<2>(path, header, row)?;
        Ok(SlipLabel { slip, fail })
    })
}

fn read_meta(path: &Path) -> Result<PscMeta> {
    let table = read_table(path)?;
    super::csv_parse::check_header(path, &table.header, &META_COLUMNS)?;
    let [row] = table.rows.as_slice() else {
        bail!("{}: expected one data row, found {}", path.display(), table.rows.len());
    };
    let field = |col: usize| (At { path, line: row.line, col, name: META_COLUMNS[col] }, &row.fields[col]);
    let (at, value) = field(0);
    let dropped = parse_flag(at, value)?;
    let (at, value) = field(3);
    let frequency_hz = parse_f64(at, value)?;
    if frequency_hz <= 0.0 {
        return Err(at.error("not a positive rate", value));
    }
    let (at, value) = field(4);
    let start_time_s = parse_wall_time_s(at, value)?;
    let (at, value) = field(5);
    let stop_time_s = parse_wall_time_s(at, value)?;
    Ok(PscMeta {
        dropped,
        notes: row.fields[1].to_owned(),
        sensor_type: row.fields[2].to_owned(),
        frequency_hz,
        start_time_s,
        stop_time_s,
        fields: table.header.iter().cloned().zip(row.fields.iter().map(str::to_owned)).collect(),
    })
}
