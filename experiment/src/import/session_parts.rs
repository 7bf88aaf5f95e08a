//! What the importers ([`super::xela_session`], [`super::xela_psc_session`])
//! write alike: the tactile channels (raw, tare, zeroed on fresh rows), the
//! marker and pose messages, JSON channels with a closed schema, the layout
//! and rig configuration of two uSkin patches seen from a wrist camera, and
//! the session file written under a hidden name and renamed when complete.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use nalgebra::Vector3;
use serde::Serialize;
use serde_json::{Value, json};
use slidetrack_core::{FingerReading, PerFinger, SensorLayout, TactileInfo, TactileLayout, TimeNs};
use slidetrack_session::vision_pose::XyzM;
use slidetrack_session::{
    ArucoDetection, ChannelHandle, FoxgloveTime, FrameTransform, PoseInFrame, Quaternion, Recorder,
    TactileRaw, TactileTare, TactileZeroed, TaxelLayout, Untyped, sensor_taxels,
};

use super::xela_csv::{MarkerPose, PatchCounts, SENSORS, TAXELS};

/// Rows averaged into the tactile baseline (`/tactile/tare`).
pub const BASELINE_ROWS: usize = 10;
/// Names of the two patches in the layout (`xela_sensor1.csv`, `xela_sensor2.csv`).
pub const SENSOR_NAMES: [&str; SENSORS] = ["sensor1", "sensor2"];
/// The patches' model (XELA uSkin 4x4 patch).
pub const SENSOR_MODEL: &str = "uSPa44";
/// The wrist camera's optical frame (x right, y down, z forward).
pub const CAMERA_FRAME: &str = "camera";
/// The robot's base frame of the end-effector pose.
pub const BASE_FRAME: &str = "base";
/// Topic of the markers' frame transforms.
pub const MARKER_TF_TOPIC: &str = "/markers/tf";
/// Topic of the robot state.
pub const ROBOT_TOPIC: &str = "/robot/state";
/// Topic of the end-effector pose.
pub const EE_POSE_TOPIC: &str = "/robot/ee_pose";

/// A JSON Schema array of `n` numbers.
pub(crate) fn number_array(n: usize, description: &str) -> Value {
    json!({"type": "array", "items": {"type": "number"}, "minItems": n, "maxItems": n, "description": description})
}

/// A JSON Schema object with exactly `properties`, all required.
pub(crate) fn closed_schema(title: &str, properties: Value) -> Value {
    let required: Vec<&String> = properties.as_object().map(|m| m.keys().collect()).unwrap_or_default();
    json!({
        "$schema": slidetrack_session::JSON_SCHEMA_DIALECT,
        "title": title,
        "type": "object",
        "properties": properties,
        "required": required,
        "additionalProperties": false,
    })
}

/// A JSON channel on `topic` whose schema name is the schema's `title`.
pub(crate) fn json_channel(
    rec: &Recorder,
    topic: &str,
    schema: &Value,
    description: &str,
) -> Result<ChannelHandle<Untyped>> {
    let name = schema["title"].as_str().unwrap_or_default().to_string();
    let meta = BTreeMap::from([("description".to_string(), description.to_string())]);
    Ok(rec.register_channel(topic, &name, "jsonschema", &serde_json::to_vec(schema)?, "json", meta)?)
}

/// Logs `v` as JSON on an untyped channel (log and publish time `t`).
pub(crate) fn log_value(
    rec: &Recorder,
    ch: &ChannelHandle<Untyped>,
    t: TimeNs,
    seq: u32,
    v: &impl Serialize,
) -> Result<()> {
    Ok(rec.log(ch, t, t, seq, serde_json::to_vec(v)?)?)
}

/// The MCAP `sequence` of row `i`.
pub(crate) fn sequence_of(i: usize) -> u32 {
    u32::try_from(i).unwrap_or(u32::MAX)
}

/// The tactile source of imported sessions of `rig`: two 4x4 uSkin patches,
/// taxel `i` (CSV `txl{i+1}`) at row `i / 4`, column `i % 4` as the
/// dataset's authors lay it out. Which finger carries which patch, and how a
/// patch is oriented on it, are not documented: `finger` says so. The three
/// finger readings of the thesis's hand map the two patches as thumb =
/// sensor 1 and index = middle = sensor 2 (the pair opposite the thumb),
/// each the mean of its patch.
pub(crate) fn two_patch_info(rig: &str, rate_hz: f64) -> TactileInfo {
    let sensor = |i: usize| {
        let finger = format!("unknown (xela_sensor{}.csv)", i + 1);
        SensorLayout::grid(SENSOR_NAMES[i], SENSOR_MODEL, &finger, 4, 4)
    };
    TactileInfo {
        device: format!("{rig} CSV"),
        rate_hz,
        layout: TactileLayout { sensors: vec![sensor(0), sensor(1)] },
        fingers: PerFinger {
            thumb: FingerReading::mean(SENSOR_NAMES[0]),
            index: FingerReading::mean(SENSOR_NAMES[1]),
            middle: FingerReading::mean(SENSOR_NAMES[1]),
        },
    }
}

/// The `rig_config` of imported sessions of `rig`: no hand-eye transform is
/// known, so the "hand" frame is the wrist camera's own (identity placement)
/// and the sliding axis is `axis` (camera frame); `label --axis config` uses
/// it. `how` says in words where the axis comes from.
pub(crate) fn wrist_camera_rig_config(rig: &str, axis: [f64; 3], how: &str) -> String {
    let [x, y, z] = axis;
    format!(
        "# {rig} import: the wrist camera's optical frame stands for the hand frame\n\
         # (no hand-eye transform is known); the sliding axis is {how}.\n\
         [camera]\n\
         placement = {{ kind = \"pose\", translation_m = [0.0, 0.0, 0.0], quaternion_xyzw = [0.0, 0.0, 0.0, 1.0] }}\n\n\
         [geometry]\n\
         sliding_axis_in_hand = [{x:?}, {y:?}, {z:?}]\n"
    )
}

/// Both patches of a row as one scan (sensor 1's 16 taxels, then sensor 2's).
pub(crate) fn scan_of_patches(patches: [&PatchCounts; SENSORS]) -> Vec<[u16; 3]> {
    patches.iter().flat_map(|p| p.iter().copied()).collect()
}

/// A detection of `pose` (a missed one for `None`), with its position along
/// the unit sliding `axis`.
pub(crate) fn marker_detection(pose: Option<&MarkerPose>, axis: &Vector3<f64>) -> ArucoDetection {
    let Some(p) = pose else { return ArucoDetection::missed() };
    let [x, y, z, w] = p.orientation_in_camera_xyzw;
    ArucoDetection {
        detected: true,
        marker_id: None,
        corners_px: None,
        position_in_camera_m: Some(p.position_in_camera_m),
        orientation_in_camera: Some(Quaternion { x, y, z, w }),
        position_on_axis_m: Some(axis.dot(&Vector3::from(p.position_in_camera_m))),
        reprojection_error_px: None,
    }
}

/// A `foxglove.PoseInFrame` at `t`.
pub(crate) fn pose_of(t: TimeNs, frame: &str, position: [f64; 3], xyzw: [f64; 4]) -> PoseInFrame {
    let [x, y, z, w] = xyzw;
    let mut pose =
        PoseInFrame { timestamp: FoxgloveTime::from(t), frame_id: frame.into(), ..PoseInFrame::default() };
    pose.pose.position = XyzM { x: position[0], y: position[1], z: position[2] };
    pose.pose.orientation = Quaternion { x, y, z, w };
    pose
}

/// `camera` -> `child` at `t`, the marker's pose.
pub(crate) fn transform_of(t: TimeNs, child: &str, p: &MarkerPose) -> FrameTransform {
    let [x, y, z, w] = p.orientation_in_camera_xyzw;
    let [px, py, pz] = p.position_in_camera_m;
    FrameTransform {
        timestamp: FoxgloveTime::from(t),
        parent_frame_id: CAMERA_FRAME.into(),
        child_frame_id: child.into(),
        translation: XyzM { x: px, y: py, z: pz },
        rotation: Quaternion { x, y, z, w },
    }
}

/// `/tactile/raw`, `/tactile/tare`, `/tactile/zeroed`.
pub(crate) struct TactileChannels {
    raw: ChannelHandle<TactileRaw>,
    tare: ChannelHandle<TactileTare>,
    zeroed: ChannelHandle<TactileZeroed>,
}

impl TactileChannels {
    /// Registers the three channels, the layout of `info` on `/tactile/raw`.
    pub(crate) fn register(rec: &Recorder, info: &TactileInfo) -> Result<TactileChannels> {
        Ok(TactileChannels {
            raw: rec.register::<TactileRaw>(TaxelLayout::new(info).channel_metadata())?,
            tare: rec.register::<TactileTare>(BTreeMap::new())?,
            zeroed: rec.register::<TactileZeroed>(BTreeMap::new())?,
        })
    }
}

/// Writes the tactile rows of a sequence: every row on `/tactile/raw`; once,
/// at t = 0, the mean of the first [`BASELINE_ROWS`] rows on
/// `/tactile/tare`; and raw minus that mean on `/tactile/zeroed`, only on
/// rows whose counts differ from the previous row's (a repeated row is the
/// sensor's last reading again, not a new one).
pub(crate) struct TactileWriter<'a> {
    ch: &'a TactileChannels,
    layout: &'a TactileLayout,
    base: Vec<[f64; 3]>,
    previous: Option<Vec<[u16; 3]>>,
    /// Rows written on `/tactile/zeroed` so far.
    pub fresh: usize,
}

impl<'a> TactileWriter<'a> {
    /// Logs the baseline of `first` (the first rows, at most
    /// [`BASELINE_ROWS`] used) and returns the writer of the rows.
    pub(crate) fn start(
        rec: &Recorder,
        ch: &'a TactileChannels,
        layout: &'a TactileLayout,
        first: &[Vec<[u16; 3]>],
    ) -> Result<TactileWriter<'a>> {
        let first = &first[..first.len().min(BASELINE_ROWS)];
        let mut sum = vec![[0.0; 3]; SENSORS * TAXELS];
        for scan in first {
            for (s, v) in sum.iter_mut().zip(scan) {
                for a in 0..3 {
                    s[a] += f64::from(v[a]);
                }
            }
        }
        let n = (first.len() as f64).max(1.0);
        let base: Vec<[f64; 3]> = sum.into_iter().map(|s| s.map(|v| v / n)).collect();
        let samples = u32::try_from(first.len()).unwrap_or(u32::MAX);
        let tare = TactileTare { samples, baseline: sensor_taxels(layout, &base) };
        rec.log_json(&ch.tare, TimeNs::ZERO, TimeNs::ZERO, 0, &tare)?;
        Ok(TactileWriter { ch, layout, base, previous: None, fresh: 0 })
    }

    /// Writes row `i` (`scan`) at `t`.
    pub(crate) fn write(&mut self, rec: &Recorder, t: TimeNs, i: usize, scan: Vec<[u16; 3]>) -> Result<()> {
        let seq = sequence_of(i);
        let raw = TactileRaw { sequence: i as u64, sensors: sensor_taxels(self.layout, &scan) };
        rec.log_json(&self.ch.raw, t, t, seq, &raw)?;
        if self.previous.as_ref() != Some(&scan) {
            let zeroed: Vec<[f64; 3]> = scan
                .iter()
                .zip(&self.base)
                .map(|(v, b)| std::array::from_fn(|a| f64::from(v[a]) - b[a]))
                .collect();
            let msg = TactileZeroed { sensors: sensor_taxels(self.layout, &zeroed) };
            rec.log_json(&self.ch.zeroed, t, t, seq, &msg)?;
            self.fresh += 1;
        }
        self.previous = Some(scan);
        Ok(())
    }
}

/// Writes `path` through `write`, which gets a hidden temporary file in the
/// same folder, renamed to `path` only when `write` succeeds (a failed
/// import leaves no file that looks finished). An existing `path` is an
/// error unless `overwrite`.
pub(crate) fn write_atomically<T>(
    path: &Path,
    overwrite: bool,
    write: impl FnOnce(&Path) -> Result<T>,
) -> Result<T> {
    if path.exists() && !overwrite {
        bail!("{} already exists; pass --overwrite to replace it", path.display());
    }
    let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("session.mcap");
    let tmp = path.with_file_name(format!(".{name}.partial-{}", std::process::id()));
    let written = match write(&tmp) {
        Ok(v) => v,
        Err(e) => {
            let _ = std::fs::remove_file(&tmp);
            return Err(e);
        }
    };
    std::fs::rename(&tmp, path).with_context(|| {
        let _ = std::fs::remove_file(&tmp);
        format!("cannot write {}", path.display())
    })?;
    Ok(written)
}

/// `<out_dir>/<name>.mcap`.
pub(crate) fn session_file(out_dir: &Path, name: &str) -> PathBuf {
    out_dir.join(format!("{name}.mcap"))
}
