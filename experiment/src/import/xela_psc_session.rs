//! xela-psc trials ([`super::xela_psc`]) written as sessions: one `.mcap`
//! per trial, every value of every CSV file on a channel or in the metadata
//! (see `docs/real-data.md`, "The xela-psc trials").
//!
//! Times: row `i` of every file is logged at `robot_state.csv`'s `time[i]`
//! (the controller's clock, 0 at the first row); rows a file has beyond the
//! robot rows would follow at `1 / frequency_hz` each.
//!
//! | topic | schema | per row |
//! |---|---|---|
//! | `/tactile/raw` | `slidetrack.TactileRaw` | both patches, 2 x 16 taxels x 3 counts |
//! | `/tactile/tare` | `slidetrack.TactileTare` | once: the mean of the first [`BASELINE_ROWS`] rows |
//! | `/tactile/zeroed` | `slidetrack.TactileZeroed` | rows whose counts changed (as xela-imanlab) |
//! | `/aruco/detections` | `slidetrack.ArucoDetection` | the marker (missed when not seen) |
//! | `/markers/marker1/pose` | `foxglove.PoseInFrame` | when the marker was seen |
//! | `/markers/tf` | `foxglove.FrameTransform` | `camera` -> `marker1`, when seen |
//! | `/robot/state` | `slidetrack.RobotTransformState` | joints, velocities, 4x4 pose, `v_x`, `v_y`, `time` |
//! | `/robot/ee_pose` | `foxglove.PoseInFrame` | end-effector pose in `base` |
//! | `/slip/label` | `slidetrack.SlipLabel` | `slip`, `fail` as written |
//!
//! The dataset has no gripper width: no `/hand/state`. The session writes to
//! a hidden temporary file in the output folder, renamed to `<trial>.mcap`
//! only when complete.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};
use serde_json::{Value, json};
use slidetrack_core::{TactileInfo, TimeNs};
use slidetrack_session::{
    ArucoDetection, ChannelHandle, ChannelMessage, Recorder, RecorderOptions, SessionMetadata,
    TAXEL_LAYOUT_KEY, TaxelLayout, Untyped, VisionPose,
};

pub use super::robot_state::{RobotTransformStateMessage, robot_transform_schema};
pub use super::session_parts::{
    BASE_FRAME, BASELINE_ROWS, CAMERA_FRAME, EE_POSE_TOPIC, MARKER_TF_TOPIC, ROBOT_TOPIC, SENSOR_MODEL,
    SENSOR_NAMES,
};
use super::session_parts::{
    TactileChannels, TactileWriter, closed_schema, json_channel, log_value, marker_detection, pose_of,
    scan_of_patches, sequence_of, session_file, transform_of, two_patch_info, wrist_camera_rig_config,
    write_atomically,
};
use super::xela_csv::PatchCounts;
use super::xela_psc::{PscSequence, SlipLabel};
pub use super::xela_session::ImportOptions;

/// `rig` of imported sessions.
pub const RIG_NAME: &str = "xela-psc";
/// Metadata record holding every value of `meta_data.csv` and the import's facts.
pub const SOURCE_METADATA: &str = "xela_psc";
/// The object (the dataset's README: "a box shaped object").
pub const OBJECT: &str = "box";
/// The sliding direction in the wrist camera's optical frame: the principal
/// direction of the marker's displacements from its first sighting, pooled
/// over the seven trials (`experiment/src/import/xela_psc/tests.rs`);
/// normalised on use.
pub const SLIDING_AXIS_IN_CAMERA: [f64; 3] = [-0.05, -0.58, 0.81];
/// Topic of the marker's pose (the one marker, named as xela-imanlab's marker 1).
pub const MARKER_POSE_TOPIC: &str = "/markers/marker1/pose";
/// Frame of the marker in `/markers/tf`.
pub const MARKER_FRAME: &str = "marker1";
/// Topic of the slip labels.
pub const SLIP_TOPIC: &str = "/slip/label";

/// `/slip/label`: one row of `slip_label.csv`, as written.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct SlipLabelMessage {
    /// `slip` (0.0 or 1.0 in the published trials).
    pub slip: f64,
    /// `fail` (0.0 or 1.0 in the published trials).
    pub fail: f64,
}

impl From<&SlipLabel> for SlipLabelMessage {
    fn from(l: &SlipLabel) -> SlipLabelMessage {
        SlipLabelMessage { slip: l.slip, fail: l.fail }
    }
}

/// The JSON Schema of `/slip/label`.
pub fn slip_label_schema() -> Value {
    closed_schema(
        "slidetrack.SlipLabel",
        json!({
            "slip": {"type": "number", "description": "slip_label.csv slip as written (1.0: the authors label the row as slip, from the marker's motion relative to the hand)"},
            "fail": {"type": "number", "description": "slip_label.csv fail as written (1.0 exactly where the marker is not seen, in the published trials)"},
        }),
    )
}

/// The tactile source of imported sessions (see [`two_patch_info`]'s rules,
/// the same as xela-imanlab's).
pub fn tactile_info(rate_hz: f64) -> TactileInfo {
    two_patch_info(RIG_NAME, rate_hz)
}

/// The `rig_config` of imported sessions: the camera frame stands for the
/// hand frame; the sliding axis is [`SLIDING_AXIS_IN_CAMERA`].
pub fn rig_config_toml() -> String {
    wrist_camera_rig_config(
        RIG_NAME,
        SLIDING_AXIS_IN_CAMERA,
        "the marker's principal\n# direction pooled over the seven trials (docs/real-data.md)",
    )
}

/// What an import wrote.
#[derive(Clone, Debug, PartialEq)]
pub struct ImportReport {
    /// The session file.
    pub path: PathBuf,
    /// Rows of the longest file.
    pub rows: usize,
    /// Rows every file has.
    pub shared_rows: usize,
    /// Rows whose tactile counts changed (messages on `/tactile/zeroed`).
    pub fresh_scans: usize,
    /// Rows on which the marker was seen.
    pub marker_seen: usize,
    /// Rows with `slip` != 0.
    pub slip_rows: usize,
    /// Rows with `fail` != 0.
    pub fail_rows: usize,
    /// Time of the last row minus that of the first (s).
    pub duration_s: f64,
    /// Mean row rate over the `time` column (Hz): (rows - 1) / duration.
    pub rate_hz: f64,
}

/// The session file of `seq` in `out_dir`.
pub fn session_path(out_dir: &Path, seq: &PscSequence) -> PathBuf {
    session_file(out_dir, &seq.name)
}

/// Time of the last row minus that of the first (s).
fn duration_s(seq: &PscSequence) -> f64 {
    seq.time_s(seq.rows().saturating_sub(1)) - seq.time_s(0)
}

/// Mean row rate over the time column (Hz); `frequency_hz` when the rows
/// span no time.
pub fn rate_hz(seq: &PscSequence) -> f64 {
    let d = duration_s(seq);
    if d > 0.0 { seq.rows().saturating_sub(1) as f64 / d } else { seq.meta.frequency_hz }
}

/// Both patches of row `i`; `None` past both files' ends.
fn tactile_row(seq: &PscSequence, i: usize) -> Result<Option<[&PatchCounts; 2]>> {
    let [a, b] = &seq.tactile;
    match (a.get(i), b.get(i)) {
        (Some(a), Some(b)) => Ok(Some([a, b])),
        (None, None) => Ok(None),
        _ => bail!(
            "{}: xela_sensor1.csv and xela_sensor2.csv have different row counts ({} and {})",
            seq.name,
            a.len(),
            b.len()
        ),
    }
}

/// Channels of an imported session.
struct Channels {
    tactile: TactileChannels,
    aruco: ChannelHandle<ArucoDetection>,
    marker_pose: ChannelHandle<Untyped>,
    marker_tf: ChannelHandle<Untyped>,
    robot: ChannelHandle<Untyped>,
    ee_pose: ChannelHandle<Untyped>,
    slip: ChannelHandle<Untyped>,
}

impl Channels {
    fn register(rec: &Recorder, info: &TactileInfo) -> Result<Channels> {
        let pose_schema = VisionPose::json_schema();
        let tf_schema = slidetrack_session::vision_pose::MaskUkfTransform::json_schema();
        let what = "the marker of marker.csv, camera_from_marker, only when seen";
        Ok(Channels {
            tactile: TactileChannels::register(rec, info)?,
            aruco: rec.register::<ArucoDetection>(BTreeMap::new())?,
            marker_pose: json_channel(rec, MARKER_POSE_TOPIC, &pose_schema, what)?,
            marker_tf: json_channel(rec, MARKER_TF_TOPIC, &tf_schema, "camera -> marker1, when seen")?,
            robot: json_channel(rec, ROBOT_TOPIC, &robot_transform_schema(), "robot_state.csv")?,
            ee_pose: json_channel(rec, EE_POSE_TOPIC, &pose_schema, "ee_T_* in the base frame")?,
            slip: json_channel(
                rec,
                SLIP_TOPIC,
                &slip_label_schema(),
                "slip_label.csv: the authors' labels from the marker's motion relative to the hand",
            )?,
        })
    }
}

/// Writes the messages of every row; returns (fresh scans, marker rows seen).
fn write_rows(
    rec: &Recorder,
    ch: &Channels,
    seq: &PscSequence,
    info: &TactileInfo,
) -> Result<(usize, usize)> {
    let mut first = Vec::new();
    for i in 0..BASELINE_ROWS {
        let Some(patches) = tactile_row(seq, i)? else { break };
        first.push(scan_of_patches(patches));
    }
    let mut tactile = TactileWriter::start(rec, &ch.tactile, &info.layout, &first)?;
    let axis = Vector3::from(SLIDING_AXIS_IN_CAMERA).normalize();
    let mut seen = 0;
    for i in 0..seq.rows() {
        let t = TimeNs::from_secs_f64(seq.time_s(i));
        let n = sequence_of(i);
        if let Some(patches) = tactile_row(seq, i)? {
            tactile.write(rec, t, i, scan_of_patches(patches))?;
        }
        if let Some(marker) = seq.markers.get(i) {
            rec.log_json(&ch.aruco, t, t, n, &marker_detection(marker.as_ref(), &axis))?;
            if let Some(m) = marker {
                seen += 1;
                let pose = pose_of(t, CAMERA_FRAME, m.position_in_camera_m, m.orientation_in_camera_xyzw);
                log_value(rec, &ch.marker_pose, t, n, &pose)?;
                log_value(rec, &ch.marker_tf, t, n, &transform_of(t, MARKER_FRAME, m))?;
            }
        }
        if let Some(r) = seq.robot.get(i) {
            let msg = RobotTransformStateMessage::from(r);
            log_value(rec, &ch.robot, t, n, &msg)?;
            let q = msg.ee_orientation_in_base;
            let ee = pose_of(t, BASE_FRAME, msg.ee_position_in_base_m, [q.x, q.y, q.z, q.w]);
            log_value(rec, &ch.ee_pose, t, n, &ee)?;
        }
        if let Some(l) = seq.labels.get(i) {
            log_value(rec, &ch.slip, t, n, &SlipLabelMessage::from(l))?;
        }
    }
    Ok((tactile.fresh, seen))
}

/// The `slidetrack` metadata record of `seq`.
fn session_metadata(seq: &PscSequence, info: &TactileInfo) -> BTreeMap<String, String> {
    let start = std::time::UNIX_EPOCH + std::time::Duration::from_secs_f64(seq.meta.start_time_s.max(0.0));
    let metadata = SessionMetadata {
        software_version: env!("CARGO_PKG_VERSION").into(),
        rig: RIG_NAME.into(),
        rig_config: rig_config_toml(),
        object: OBJECT.into(),
        object_config: String::new(),
        trial: seq.name.clone(),
        seed: 0,
        started_at: humantime::format_rfc3339_seconds(start).to_string(),
    };
    let mut map = metadata.to_map();
    map.insert(TAXEL_LAYOUT_KEY.into(), TaxelLayout::new(info).to_json());
    map
}

fn count(labels: &[SlipLabel], f: impl Fn(&SlipLabel) -> f64) -> usize {
    labels.iter().filter(|l| f(l) != 0.0).count()
}

/// The [`SOURCE_METADATA`] record: every `meta_data.csv` value as written
/// (`meta.<column>`), row counts, the rate and the rules, in words.
fn source_metadata(seq: &PscSequence, source: &Path) -> BTreeMap<String, String> {
    let mut map: BTreeMap<String, String> =
        seq.meta.fields.iter().map(|(k, v)| (format!("meta.{k}"), v.clone())).collect();
    let [s1, s2, marker, robot, label] = seq.file_rows().map(|n| n.to_string());
    let entries = [
        ("source", source.display().to_string()),
        ("sequence", seq.name.clone()),
        ("dropped", seq.meta.dropped.to_string()),
        ("rows", seq.rows().to_string()),
        ("shared_rows", seq.shared_rows().to_string()),
        ("rows.xela_sensor1", s1),
        ("rows.xela_sensor2", s2),
        ("rows.marker", marker),
        ("rows.robot_state", robot),
        ("rows.slip_label", label),
        ("slip_rows", count(&seq.labels, |l| l.slip).to_string()),
        ("fail_rows", count(&seq.labels, |l| l.fail).to_string()),
        ("duration_s", duration_s(seq).to_string()),
        ("rate_hz", rate_hz(seq).to_string()),
        (
            "timing",
            "row i of every file at robot_state.csv time[i] (s); rows beyond the robot rows at 1 / frequency_hz more each".into(),
        ),
        ("baseline", format!("/tactile/tare: mean of the first {BASELINE_ROWS} rows (already in grasp)")),
        ("zeroed", "/tactile/zeroed only on rows whose counts changed (as xela-imanlab)".into()),
        (
            "marker_not_seen",
            "all seven values 10.0 in marker.csv: no pose message, a missed detection".into(),
        ),
        (
            "slip_label",
            "slip_label.csv as written: the authors' labels from the marker's motion relative to the hand; \
             fail is 1.0 exactly where the marker is not seen"
                .into(),
        ),
        ("fingers", "unknown; thumb = sensor1, index = middle = sensor2 (patch means)".into()),
        ("sliding_axis_in_camera", format!("{SLIDING_AXIS_IN_CAMERA:?}")),
    ];
    map.extend(entries.into_iter().map(|(k, v)| (k.to_string(), v)));
    map
}

/// Writes `seq` (read from `source`) as `<out_dir>/<name>.mcap`.
pub fn import_sequence(
    seq: &PscSequence,
    source: &Path,
    out_dir: &Path,
    options: ImportOptions,
) -> Result<ImportReport> {
    let path = session_path(out_dir, seq);
    let rate = rate_hz(seq);
    let info = tactile_info(rate);
    let (fresh_scans, marker_seen) = write_atomically(&path, options.overwrite, |tmp| {
        let options = RecorderOptions { overwrite: true, ..RecorderOptions::default() };
        let rec = Recorder::create_with_options(tmp, session_metadata(seq, &info), options)?;
        let channels = Channels::register(&rec, &info)?;
        let counts = write_rows(&rec, &channels, seq, &info)?;
        rec.metadata(SOURCE_METADATA, source_metadata(seq, source))?;
        rec.finish_with_outcome(true, None).with_context(|| format!("cannot finish {}", tmp.display()))?;
        Ok(counts)
    })?;
    Ok(ImportReport {
        path,
        rows: seq.rows(),
        shared_rows: seq.shared_rows(),
        fresh_scans,
        marker_seen,
        slip_rows: count(&seq.labels, |l| l.slip),
        fail_rows: count(&seq.labels, |l| l.fail),
        duration_s: duration_s(seq),
        rate_hz: rate,
    })
}
