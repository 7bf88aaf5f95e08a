//! xela-imanlab sequences ([`super::xela_csv`]) written as sessions: one
//! `.mcap` per sequence, every value of every CSV file on a channel or in
//! the metadata (see `docs/real-data.md`, "Imported, labelled, trained").
//!
//! Times: the files hold no per-row time, so row `i` of every file is logged
//! at `i / frequency_hz` (s), the time [`super::xela_csv::XelaFrame::t_s`]
//! gives it; rows a file has beyond the others (the extra tactile row) follow
//! at the same spacing.
//!
//! | topic | schema | per row |
//! |---|---|---|
//! | `/tactile/raw` | `slidetrack.TactileRaw` | both patches, 2 x 16 taxels x 3 counts |
//! | `/tactile/tare` | `slidetrack.TactileTare` | once: the mean of the first [`BASELINE_ROWS`] rows |
//! | `/tactile/zeroed` | `slidetrack.TactileZeroed` | rows whose counts changed (the ~10 Hz refresh) |
//! | `/aruco/detections` | `slidetrack.ArucoDetection` | marker 1 (missed when not seen) |
//! | `/markers/marker1/pose`, `/markers/marker2/pose` | `foxglove.PoseInFrame` | when that marker was seen |
//! | `/markers/tf` | `foxglove.FrameTransform` | `camera` -> `marker1` / `marker2`, when seen |
//! | `/hand/state` | `slidetrack.HandState` | `opening`: the gripper's opening width |
//! | `/robot/state` | `slidetrack.RobotState` | joints, velocities, end-effector pose |
//! | `/robot/ee_pose` | `foxglove.PoseInFrame` | end-effector pose in `base` |
//!
//! The session writes to a hidden temporary file in the output folder and
//! is renamed to `<sequence>.mcap` only when complete, so a failed import
//! leaves no file that looks finished.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use nalgebra::Vector3;
use slidetrack_core::{TactileInfo, TimeNs};
use slidetrack_session::{
    ArucoDetection, ChannelHandle, ChannelMessage, HandState, Recorder, RecorderOptions, SessionMetadata,
    TAXEL_LAYOUT_KEY, TaxelLayout, Untyped, VisionPose,
};

pub use super::robot_state::{RobotStateMessage, robot_schema};
pub use super::session_parts::{
    BASE_FRAME, BASELINE_ROWS, CAMERA_FRAME, EE_POSE_TOPIC, MARKER_TF_TOPIC, ROBOT_TOPIC, SENSOR_MODEL,
    SENSOR_NAMES,
};
use super::session_parts::{
    TactileChannels, TactileWriter, json_channel, log_value, marker_detection, pose_of, scan_of_patches,
    sequence_of, session_file, transform_of, two_patch_info, wrist_camera_rig_config, write_atomically,
};
use super::xela_csv::{MarkerPose, PatchCounts, RobotState, SENSORS, XelaSequence};

/// `rig` of imported sessions.
pub const RIG_NAME: &str = "xela-imanlab";
/// Metadata record holding every value of `meta_data.csv` and the import's facts.
pub const SOURCE_METADATA: &str = "xela_imanlab";
/// The sliding direction in the wrist camera's optical frame: the principal
/// direction of marker 1's displacements pooled over the 53 sequences
/// (`docs/real-data.md`, "What sliding looks like"); normalised on use.
pub const SLIDING_AXIS_IN_CAMERA: [f64; 3] = [-0.08, -0.60, 0.80];
/// Topics of the markers' poses.
pub const MARKER_POSE_TOPICS: [&str; 2] = ["/markers/marker1/pose", "/markers/marker2/pose"];

/// The tactile source of imported sessions: two 4x4 uSkin patches, taxel
/// `i` (CSV `txl{i+1}`) at row `i / 4`, column `i % 4` as the dataset's
/// authors lay it out. Which finger carries which patch, and how a patch
/// is oriented on it, are not documented: `finger` says so. The three
/// finger readings of the thesis's hand map the two patches as thumb =
/// sensor 1 and index = middle = sensor 2 (the pair opposite the thumb),
/// each the mean of its patch.
pub fn tactile_info(rate_hz: f64) -> TactileInfo {
    two_patch_info(RIG_NAME, rate_hz)
}

/// The `rig_config` of imported sessions: no hand-eye transform is known, so
/// the "hand" frame is the wrist camera's own (identity placement) and the
/// sliding axis is [`SLIDING_AXIS_IN_CAMERA`]; `label --axis config` uses it.
pub fn rig_config_toml() -> String {
    wrist_camera_rig_config(
        RIG_NAME,
        SLIDING_AXIS_IN_CAMERA,
        "marker 1's principal\n# direction pooled over the dataset (docs/real-data.md)",
    )
}

/// How to import.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ImportOptions {
    /// Replace an existing session file.
    pub overwrite: bool,
}

/// What an import wrote.
#[derive(Clone, Debug, PartialEq)]
pub struct ImportReport {
    /// The session file.
    pub path: PathBuf,
    /// Rows of the longest file (messages on `/tactile/raw` when it is a tactile file).
    pub rows: usize,
    /// Rows every file has.
    pub shared_rows: usize,
    /// Rows whose tactile counts changed (messages on `/tactile/zeroed`).
    pub fresh_scans: usize,
    /// Rows on which marker 1 and marker 2 were seen.
    pub markers_seen: [usize; 2],
    /// Duration (s).
    pub duration_s: f64,
}

/// The session file of `seq` in `out_dir`.
pub fn session_path(out_dir: &Path, seq: &XelaSequence) -> PathBuf {
    session_file(out_dir, &seq.name)
}

/// The rows of one sequence, each file's row `i` (shared rows, then tails).
struct Rows<'a> {
    seq: &'a XelaSequence,
}

impl<'a> Rows<'a> {
    fn tactile(&self, i: usize) -> Result<Option<[&'a PatchCounts; SENSORS]>> {
        let n = self.seq.frames.len();
        if let Some(f) = self.seq.frames.get(i) {
            return Ok(Some([&f.tactile[0], &f.tactile[1]]));
        }
        match (self.seq.tail.tactile[0].get(i - n), self.seq.tail.tactile[1].get(i - n)) {
            (Some(a), Some(b)) => Ok(Some([a, b])),
            (None, None) => Ok(None),
            _ => bail!(
                "{}: xela_sensor1.csv and xela_sensor2.csv have different row counts ({} and {})",
                self.seq.name,
                n + self.seq.tail.tactile[0].len(),
                n + self.seq.tail.tactile[1].len()
            ),
        }
    }

    fn markers(&self, i: usize) -> Option<&'a [Option<MarkerPose>; 2]> {
        let n = self.seq.frames.len();
        self.seq.frames.get(i).map(|f| &f.markers).or_else(|| self.seq.tail.markers.get(i - n))
    }

    fn robot(&self, i: usize) -> Option<&'a RobotState> {
        let n = self.seq.frames.len();
        self.seq.frames.get(i).map(|f| &f.robot).or_else(|| self.seq.tail.robot.get(i - n))
    }

    fn count(&self) -> usize {
        let t = &self.seq.tail;
        let extra = [t.tactile[0].len(), t.tactile[1].len(), t.markers.len(), t.robot.len()];
        self.seq.frames.len() + extra.into_iter().max().unwrap_or(0)
    }
}

/// Channels of an imported session.
struct Channels {
    tactile: TactileChannels,
    aruco: ChannelHandle<ArucoDetection>,
    marker_pose: [ChannelHandle<Untyped>; 2],
    marker_tf: ChannelHandle<Untyped>,
    gripper: ChannelHandle<HandState>,
    robot: ChannelHandle<Untyped>,
    ee_pose: ChannelHandle<Untyped>,
}

impl Channels {
    fn register(rec: &Recorder, info: &TactileInfo) -> Result<Channels> {
        let pose_schema = VisionPose::json_schema();
        let tf_schema = slidetrack_session::vision_pose::MaskUkfTransform::json_schema();
        let marker = |k: usize| {
            let what = format!("marker {} of marker.csv, camera_from_marker, only when seen", k + 1);
            json_channel(rec, MARKER_POSE_TOPICS[k], &pose_schema, &what)
        };
        Ok(Channels {
            tactile: TactileChannels::register(rec, info)?,
            aruco: rec.register::<ArucoDetection>(BTreeMap::new())?,
            marker_pose: [marker(0)?, marker(1)?],
            marker_tf: json_channel(
                rec,
                MARKER_TF_TOPIC,
                &tf_schema,
                "camera -> marker1 / marker2, when seen",
            )?,
            gripper: rec.register::<HandState>(BTreeMap::from([(
                "description".to_string(),
                "opening = position_panda_finger (the gripper's opening width, m)".to_string(),
            )]))?,
            robot: json_channel(rec, ROBOT_TOPIC, &robot_schema(), "robot_state.csv")?,
            ee_pose: json_channel(rec, EE_POSE_TOPIC, &pose_schema, "ee_state_* in the base frame")?,
        })
    }
}

/// Writes the messages of every row; returns (fresh scans, markers seen).
fn write_rows(
    rec: &Recorder,
    ch: &Channels,
    rows: &Rows<'_>,
    info: &TactileInfo,
) -> Result<(usize, [usize; 2])> {
    let frequency_hz = rows.seq.meta.frequency_hz;
    let mut first = Vec::new();
    for i in 0..BASELINE_ROWS {
        let Some(patches) = rows.tactile(i)? else { break };
        first.push(scan_of_patches(patches));
    }
    let mut tactile = TactileWriter::start(rec, &ch.tactile, &info.layout, &first)?;
    let axis = Vector3::from(SLIDING_AXIS_IN_CAMERA).normalize();
    let mut seen = [0, 0];
    for i in 0..rows.count() {
        let t = TimeNs::from_secs_f64(i as f64 / frequency_hz);
        let seq = sequence_of(i);
        if let Some(patches) = rows.tactile(i)? {
            tactile.write(rec, t, i, scan_of_patches(patches))?;
        }
        if let Some(markers) = rows.markers(i) {
            rec.log_json(&ch.aruco, t, t, seq, &marker_detection(markers[0].as_ref(), &axis))?;
            for (k, m) in markers.iter().enumerate() {
                let Some(m) = m else { continue };
                seen[k] += 1;
                let pose = pose_of(t, CAMERA_FRAME, m.position_in_camera_m, m.orientation_in_camera_xyzw);
                log_value(rec, &ch.marker_pose[k], t, seq, &pose)?;
                log_value(rec, &ch.marker_tf, t, seq, &transform_of(t, &format!("marker{}", k + 1), m))?;
            }
        }
        if let Some(r) = rows.robot(i) {
            let gripper =
                HandState { finger_travel: Vec::new(), opening: Some(r.finger_position_m), gripper: None };
            rec.log_json(&ch.gripper, t, t, seq, &gripper)?;
            log_value(rec, &ch.robot, t, seq, &RobotStateMessage::from(r))?;
            let ee = pose_of(t, BASE_FRAME, r.ee_position_in_base_m, r.ee_orientation_in_base_xyzw);
            log_value(rec, &ch.ee_pose, t, seq, &ee)?;
        }
    }
    Ok((tactile.fresh, seen))
}

/// The `slidetrack` metadata record of `seq`.
fn session_metadata(seq: &XelaSequence, info: &TactileInfo) -> BTreeMap<String, String> {
    let start = std::time::UNIX_EPOCH + std::time::Duration::from_secs_f64(seq.meta.start_time_s.max(0.0));
    let metadata = SessionMetadata {
        software_version: env!("CARGO_PKG_VERSION").into(),
        rig: RIG_NAME.into(),
        rig_config: rig_config_toml(),
        object: seq.meta.object_name.clone(),
        object_config: String::new(),
        trial: seq.name.clone(),
        seed: 0,
        started_at: humantime::format_rfc3339_seconds(start).to_string(),
    };
    let mut map = metadata.to_map();
    map.insert(TAXEL_LAYOUT_KEY.into(), TaxelLayout::new(info).to_json());
    map
}

/// The [`SOURCE_METADATA`] record: every `meta_data.csv` value as written
/// (`meta.<column>`), the npy path, row counts and the timing rule.
fn source_metadata(seq: &XelaSequence, source: &Path, rows: usize) -> BTreeMap<String, String> {
    let mut map: BTreeMap<String, String> =
        seq.meta.fields.iter().map(|(k, v)| (format!("meta.{k}"), v.clone())).collect();
    let t = &seq.tail;
    let file_rows = |extra: usize| (seq.frames.len() + extra).to_string();
    let entries = [
        ("source", source.display().to_string()),
        ("sequence", seq.name.clone()),
        ("dropped", seq.meta.dropped.to_string()),
        ("meta_data_npy_path", seq.meta_npy_path.clone().unwrap_or_default()),
        ("meta_data_npy_present", seq.meta_npy_path.is_some().to_string()),
        ("rows", rows.to_string()),
        ("shared_rows", seq.frames.len().to_string()),
        ("rows.xela_sensor1", file_rows(t.tactile[0].len())),
        ("rows.xela_sensor2", file_rows(t.tactile[1].len())),
        ("rows.robot_state", file_rows(t.robot.len())),
        ("rows.marker", file_rows(t.markers.len())),
        ("timing", "row i of every file at i / frequency_hz s (the files have no per-row time)".into()),
        ("baseline", format!("/tactile/tare: mean of the first {BASELINE_ROWS} rows")),
        ("zeroed", "/tactile/zeroed only on rows whose counts changed (the ~10 Hz tactile refresh)".into()),
        (
            "marker_not_seen",
            "all seven values 10.0 in marker.csv: no pose message, a missed detection".into(),
        ),
        ("fingers", "unknown; thumb = sensor1, index = middle = sensor2 (patch means)".into()),
        ("sliding_axis_in_camera", format!("{SLIDING_AXIS_IN_CAMERA:?}")),
    ];
    map.extend(entries.into_iter().map(|(k, v)| (k.to_string(), v)));
    map
}

/// Writes `seq` (read from `source`) as `<out_dir>/<name>.mcap`.
pub fn import_sequence(
    seq: &XelaSequence,
    source: &Path,
    out_dir: &Path,
    options: ImportOptions,
) -> Result<ImportReport> {
    let path = session_path(out_dir, seq);
    let rows = Rows { seq };
    let count = rows.count();
    let info = tactile_info(seq.meta.frequency_hz);
    let (fresh_scans, markers_seen) =
        write_atomically(&path, options.overwrite, |tmp| write_session(seq, source, &rows, &info, tmp))?;
    Ok(ImportReport {
        path,
        rows: count,
        shared_rows: seq.frames.len(),
        fresh_scans,
        markers_seen,
        duration_s: count.saturating_sub(1) as f64 / seq.meta.frequency_hz,
    })
}

fn write_session(
    seq: &XelaSequence,
    source: &Path,
    rows: &Rows<'_>,
    info: &TactileInfo,
    tmp: &Path,
) -> Result<(usize, [usize; 2])> {
    let options = RecorderOptions { overwrite: true, ..RecorderOptions::default() };
    let rec = Recorder::create_with_options(tmp, session_metadata(seq, info), options)?;
    let channels = Channels::register(&rec, info)?;
    let counts = write_rows(&rec, &channels, rows, info)?;
    rec.metadata(SOURCE_METADATA, source_metadata(seq, source, rows.count()))?;
    rec.finish_with_outcome(true, None).with_context(|| format!("cannot finish {}", tmp.display()))?;
    Ok(counts)
}
