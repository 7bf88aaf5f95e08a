//! Reader of the xela-imanlab recordings (imanlab's
//! `tactile_prediction_flat_dataset`, Mandil, Nazari and Ghalamzan E, RSS
//! 2022): teleoperated pick-and-move sequences of a Franka Panda whose two
//! fingers carry XELA uSkin 4x4 patches, with two ArUco markers on the held
//! object seen by a RealSense D435 on the wrist.
//!
//! One sequence is a folder (`data_sample_<date>`) of five CSV files written
//! by pandas from one ROS `ApproximateTimeSynchronizer` callback per row:
//! `xela_sensor1.csv` and `xela_sensor2.csv` (48 raw counts each),
//! `robot_state.csv` (22 columns), `marker.csv` (two poses, 14 columns) and
//! `meta_data.csv` (one row), plus, in most folders, `meta_data.csv.npy`
//! (the path of `meta_data.csv` on the recording PC). The files carry no
//! per-row time: [`XelaFrame::t_s`] is the row index over the recorded mean
//! rate. `docs/real-data.md` tells what the columns mean and how that was
//! established.
//!
//! [`read_sequence`] keeps every value of every file: rows that all four data
//! files share become [`XelaFrame`]s, the rows one file has beyond the others
//! go to [`XelaTail`] (the collection script sometimes drops the last two
//! robot and marker rows but not the tactile ones), and `meta_data.csv` keeps
//! its columns as written in [`XelaMeta::fields`]. Headers must be exactly
//! the dataset's; a malformed file is an error naming file, line and column.

#[cfg(test)]
mod study;
#[cfg(test)]
mod tests;

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};

use super::csv_parse::{
    At, numbers, parse_count, parse_f64, parse_flag, parse_wall_time_s, read_npy_string, read_rows,
    read_table,
};

/// Taxels of one uSkin patch (4 x 4).
pub const TAXELS: usize = 16;
/// Tactile patches (fingers): `xela_sensor1.csv`, `xela_sensor2.csv`.
pub const SENSORS: usize = 2;
/// ArUco markers in `marker.csv`.
pub const MARKERS: usize = 2;
/// The value every field of a marker's pose takes when the marker was not seen.
pub const MARKER_NOT_SEEN: f64 = 10.0;

/// The tactile files, sensor 1 then sensor 2.
pub const TACTILE_FILES: [&str; SENSORS] = ["xela_sensor1.csv", "xela_sensor2.csv"];
/// The robot state file.
pub const ROBOT_FILE: &str = "robot_state.csv";
/// The marker file.
pub const MARKER_FILE: &str = "marker.csv";
/// The one-row metadata file.
pub const META_FILE: &str = "meta_data.csv";
/// NumPy copy of the metadata file's path on the recording PC (absent in some folders).
pub const META_NPY_FILE: &str = "meta_data.csv.npy";

/// Columns of `robot_state.csv`, in order.
pub const ROBOT_COLUMNS: [&str; 22] = [
    "position_panda_joint1",
    "position_panda_joint2",
    "position_panda_joint3",
    "position_panda_joint4",
    "position_panda_joint5",
    "position_panda_joint6",
    "position_panda_joint7",
    "position_panda_finger",
    "velocity_panda_joint1",
    "velocity_panda_joint2",
    "velocity_panda_joint3",
    "velocity_panda_joint4",
    "velocity_panda_joint5",
    "velocity_panda_joint6",
    "velocity_panda_joint7",
    "ee_state_position_x",
    "ee_state_position_y",
    "ee_state_position_z",
    "ee_state_orientation_x",
    "ee_state_orientation_y",
    "ee_state_orientation_z",
    "ee_state_orientation_w",
];

/// Columns of `marker.csv`, in order: marker 1's pose, then marker 2's.
pub const MARKER_COLUMNS: [&str; 7 * MARKERS] = [
    "marker1_position_x",
    "marker1_position_y",
    "marker1_position_z",
    "marker1_quaternion_x",
    "marker1_quaternion_y",
    "marker1_quaternion_z",
    "marker1_quaternion_w",
    "marker2_position_x",
    "marker2_position_y",
    "marker2_position_z",
    "marker2_quaternion_x",
    "marker2_quaternion_y",
    "marker2_quaternion_z",
    "marker2_quaternion_w",
];

/// Columns of a tactile file, in order: `txl1_x, txl1_y, txl1_z, txl2_x, ...,
/// txl16_z` (taxel-major, then x, y, z).
pub fn tactile_columns() -> Vec<String> {
    (1..=TAXELS).flat_map(|t| ["x", "y", "z"].map(|axis| format!("txl{t}_{axis}"))).collect()
}

/// Raw counts of one 4x4 uSkin patch: `[taxel][axis]`. Taxel `i` is the CSV
/// column group `txl{i+1}` (the dataset authors lay them out row-major, four
/// per row); axis 0, 1, 2 are the `_x`, `_y`, `_z` columns (z rises with
/// normal force). Uncalibrated 16-bit counts, baseline differs per taxel.
pub type PatchCounts = [[u16; 3]; TAXELS];

/// One sequence folder, every value of every file.
#[derive(Clone, Debug, PartialEq)]
pub struct XelaSequence {
    /// The folder name (`data_sample_2021-11-24-15-19-34`).
    pub name: String,
    /// `meta_data.csv`.
    pub meta: XelaMeta,
    /// The rows all four data files have, in file order (frame `i` is data
    /// row `i` of each file, CSV line `i + 2`).
    pub frames: Vec<XelaFrame>,
    /// Rows a data file has beyond the last shared row.
    pub tail: XelaTail,
    /// The string in `meta_data.csv.npy` (the metadata file's path on the
    /// recording PC); `None` when the folder has no such file.
    pub meta_npy_path: Option<String>,
}

/// `meta_data.csv`: one row of named values.
#[derive(Clone, Debug, PartialEq)]
pub struct XelaMeta {
    /// `object_name`: the object's id in the dataset (`"7"`).
    pub object_name: String,
    /// `object_class` (`"box"`).
    pub object_class: String,
    /// `seen` (0/1; in the published split 1 for train, 0 for test: presumably
    /// whether the object is among the training objects). `None` if absent.
    pub seen: Option<bool>,
    /// `dropped`: the object fell out of the grasp during the sequence.
    pub dropped: bool,
    /// `notes` (free text), `None` if absent.
    pub notes: Option<String>,
    /// `sensor_type` (`"xela_2fingers_noglove"`).
    pub sensor_type: String,
    /// `frequency_hz`: rows of the tactile files over the recording time
    /// (Hz), as the collection script computed it.
    pub frequency_hz: f64,
    /// `start_time`: wall clock of the recording PC when the subscription
    /// started (s since 1970-01-01 of that clock; no time zone was written).
    pub start_time_s: f64,
    /// `stop_time`: wall clock when the recording stopped (s, same clock).
    pub stop_time_s: f64,
    /// Every column as written, in file order (known ones included).
    pub fields: Vec<(String, String)>,
}

/// One CSV row of the four data files.
#[derive(Clone, Debug, PartialEq)]
pub struct XelaFrame {
    /// Data row index (0-based; CSV line `index + 2`).
    pub index: usize,
    /// Time since the first row (s): `index / meta.frequency_hz`, the mean
    /// row period. The files hold no per-row time; the true intervals vary
    /// (they appear to be whole multiples of ~1/60 s, see `docs/real-data.md`).
    pub t_s: f64,
    /// Sensor 1 and sensor 2 counts.
    pub tactile: [PatchCounts; SENSORS],
    /// Marker 1 and marker 2; `None` when all seven fields are 10.0 (not seen).
    pub markers: [Option<MarkerPose>; MARKERS],
    /// `robot_state.csv`.
    pub robot: RobotState,
}

/// Rows of a data file beyond the last row all four files have. Row `k` of a
/// list is data row `frames.len() + k` of its file.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct XelaTail {
    /// Extra rows of sensor 1 and sensor 2.
    pub tactile: [Vec<PatchCounts>; SENSORS],
    /// Extra rows of `marker.csv`.
    pub markers: Vec<[Option<MarkerPose>; MARKERS]>,
    /// Extra rows of `robot_state.csv`.
    pub robot: Vec<RobotState>,
}

impl XelaTail {
    /// No file has extra rows.
    pub fn is_empty(&self) -> bool {
        self.tactile.iter().all(Vec::is_empty) && self.markers.is_empty() && self.robot.is_empty()
    }
}

/// An ArUco marker's pose in the wrist camera's optical frame (x right, y
/// down, z forward), as the marker detector published it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MarkerPose {
    /// `markerN_position_{x,y,z}` (m).
    pub position_in_camera_m: [f64; 3],
    /// `markerN_quaternion_{x,y,z,w}`: camera-from-marker rotation.
    pub orientation_in_camera_xyzw: [f64; 4],
}

impl MarkerPose {
    /// `None` for the not-seen sentinel (all seven values 10.0); any other
    /// values are kept as written.
    pub(crate) fn from_values(v: &[f64]) -> Option<MarkerPose> {
        if v.iter().all(|&x| x == MARKER_NOT_SEEN) {
            return None;
        }
        Some(MarkerPose {
            position_in_camera_m: [v[0], v[1], v[2]],
            orientation_in_camera_xyzw: [v[3], v[4], v[5], v[6]],
        })
    }
}

/// `robot_state.csv`, one row (Franka Panda; base frame `panda_link0`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RobotState {
    /// `position_panda_joint1..7` (rad).
    pub joint_position_rad: [f64; 7],
    /// `position_panda_finger` (m). Reaches 0.079 m, beyond one Panda finger's
    /// 0.04 m travel: most likely the opening width between the fingers.
    pub finger_position_m: f64,
    /// `velocity_panda_joint1..7` (rad/s).
    pub joint_velocity_rad_s: [f64; 7],
    /// `ee_state_position_{x,y,z}`: end-effector position in the base frame (m).
    pub ee_position_in_base_m: [f64; 3],
    /// `ee_state_orientation_{x,y,z,w}`: base-from-end-effector rotation.
    pub ee_orientation_in_base_xyzw: [f64; 4],
}

impl RobotState {
    fn from_values(v: &[f64; 22]) -> RobotState {
        let array = |start: usize| -> [f64; 7] { std::array::from_fn(|i| v[start + i]) };
        RobotState {
            joint_position_rad: array(0),
            finger_position_m: v[7],
            joint_velocity_rad_s: array(8),
            ee_position_in_base_m: [v[15], v[16], v[17]],
            ee_orientation_in_base_xyzw: [v[18], v[19], v[20], v[21]],
        }
    }
}

/// Reads one sequence folder.
pub fn read_sequence(dir: &Path) -> Result<XelaSequence> {
    let name = dir
        .file_name()
        .and_then(|n| n.to_str())
        .with_context(|| format!("{}: not a folder name", dir.display()))?
        .to_owned();
    let meta = read_meta(&dir.join(META_FILE))?;
    let [t1, t2] = TACTILE_FILES.map(|f| dir.join(f));
    let tactile = [read_tactile(&t1)?, read_tactile(&t2)?];
    let robot = read_robot(&dir.join(ROBOT_FILE))?;
    let markers = read_markers(&dir.join(MARKER_FILE))?;
    let npy = dir.join(META_NPY_FILE);
    let meta_npy_path = if npy.exists() { Some(read_npy_string(&npy)?) } else { None };
    let shared = tactile.iter().map(Vec::len).chain([robot.len(), markers.len()]).min().unwrap_or(0);
    let [mut tactile1, mut tactile2] = tactile;
    let tail = XelaTail {
        tactile: [tactile1.split_off(shared), tactile2.split_off(shared)],
        markers: markers[shared..].to_vec(),
        robot: robot[shared..].to_vec(),
    };
    let frames = (0..shared)
        .map(|index| {
            let t_s = index as f64 / meta.frequency_hz;
            XelaFrame {
                index,
                t_s,
                tactile: [tactile1[index], tactile2[index]],
                markers: markers[index],
                robot: robot[index],
            }
        })
        .collect();
    Ok(XelaSequence { name, meta, frames, tail, meta_npy_path })
}

/// Reads every sequence [`find_sequences`] finds in `dirs`.
pub fn read_sequences(dirs: &[PathBuf]) -> Result<Vec<XelaSequence>> {
    find_sequences(dirs)?.iter().map(|dir| read_sequence(dir)).collect()
}

/// The sequence folders in `dirs`: each entry is a sequence folder (it holds
/// `xela_sensor1.csv`) or a folder of sequence folders (such as `train/`),
/// whose sequences are listed by name. An entry with neither is an error.
pub fn find_sequences(dirs: &[PathBuf]) -> Result<Vec<PathBuf>> {
    let mut found = Vec::new();
    for dir in dirs {
        if is_sequence_dir(dir) {
            found.push(dir.clone());
            continue;
        }
        let entries = std::fs::read_dir(dir).with_context(|| format!("{}: cannot list", dir.display()))?;
        let mut inner = Vec::new();
        for entry in entries {
            let path = entry.with_context(|| format!("{}: cannot list", dir.display()))?.path();
            if is_sequence_dir(&path) {
                inner.push(path);
            }
        }
        if inner.is_empty() {
            bail!("{}: neither a sequence folder nor a folder of sequence folders", dir.display());
        }
        inner.sort();
        found.extend(inner);
    }
    Ok(found)
}

fn is_sequence_dir(dir: &Path) -> bool {
    dir.join(TACTILE_FILES[0]).is_file()
}

/// Reads a tactile file (`xela_sensor1.csv` / `xela_sensor2.csv`: 48 counts
/// per row, [`tactile_columns`]).
pub(crate) fn read_tactile(path: &Path) -> Result<Vec<PatchCounts>> {
    let columns = tactile_columns();
    let expected: Vec<&str> = columns.iter().map(String::as_str).collect();
    read_rows(path, &expected, |path, header, row| {
        let mut patch = [[0_u16; 3]; TAXELS];
        for (col, value) in row.fields.iter().enumerate() {
            let at = At { path, line: row.line, col, name: &header[col] };
            patch[col / 3][col % 3] = parse_count(at, value)?;
        }
        Ok(patch)
    })
}

fn read_robot(path: &Path) -> Result<Vec<RobotState>> {
    read_rows(path, &ROBOT_COLUMNS, |path, header, row| {
        Ok(RobotState::from_values(&numbers::<22>(path, header, row)?))
    })
}

fn read_markers(path: &Path) -> Result<Vec<[Option<MarkerPose>; MARKERS]>> {
    read_rows(path, &MARKER_COLUMNS, |path, header, row| {
        let v = numbers::<14>(path, header, row)?;
        Ok([MarkerPose::from_values(&v[..7]), MarkerPose::from_values(&v[7..])])
    })
}

fn read_meta(path: &Path) -> Result<XelaMeta> {
    let table = read_table(path)?;
    let [row] = table.rows.as_slice() else {
        bail!("{}: expected one data row, found {}", path.display(), table.rows.len());
    };
    let fields: Vec<(String, String)> =
        table.header.iter().cloned().zip(row.fields.iter().map(str::to_owned)).collect();
    let find = |name: &'static str| -> Option<(At<'_>, &str)> {
        let col = table.header.iter().position(|h| h == name)?;
        Some((At { path, line: row.line, col, name }, &row.fields[col]))
    };
    let get =
        |name: &'static str| find(name).with_context(|| format!("{}:1: no column {name:?}", path.display()));
    let text = |name| get(name).map(|(_, v)| v.to_owned());
    let (at, value) = get("frequency_hz")?;
    let frequency_hz = parse_f64(at, value)?;
    if frequency_hz <= 0.0 {
        bail!("{}:{}: frequency_hz is {frequency_hz}, not a positive rate", path.display(), row.line);
    }
    let (at, value) = get("dropped")?;
    let dropped = parse_flag(at, value)?;
    let seen = find("seen").map(|(at, value)| parse_flag(at, value)).transpose()?;
    let (at, value) = get("start_time")?;
    let start_time_s = parse_wall_time_s(at, value)?;
    let (at, value) = get("stop_time")?;
    let stop_time_s = parse_wall_time_s(at, value)?;
    Ok(XelaMeta {
        object_name: text("object_name")?,
        object_class: text("object_class")?,
        seen,
        dropped,
        notes: find("notes").map(|(_, v)| v.to_owned()),
        sensor_type: text("sensor_type")?,
        frequency_hz,
        start_time_s,
        stop_time_s,
        fields,
    })
}
