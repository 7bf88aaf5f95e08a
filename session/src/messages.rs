//! The messages of the numeric session channels: one type per channel, each
//! with its topic, schema name and JSON Schema (see [`ChannelMessage`]).
//!
//! Field names are a stable interface, documented in `docs/session-format.md`.
//! JSON has no NaN or infinity: serde_json writes non-finite numbers as `null`,
//! which then fails to decode, so log finite values only.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};
use serde_json::Value;
use slidetrack_core::{
    FingerReading, LayoutError, PerFinger, Phase, RawTaxel, SensorLayout, TactileInfo, TactileLayout,
    TactileSample,
};

use super::schema::{Fingers, PhaseName, derived, describe_fingers};

pub use super::channel::{ChannelMessage, ChannelSpec, MESSAGE_ENCODING_JSON, SCHEMA_ENCODING_JSONSCHEMA};

/// Every channel slidetrack records, in the order of `docs/session-format.md`.
pub fn channel_specs() -> Vec<ChannelSpec> {
    use super::vision::{ArucoDetection, CameraCalibration, CompressedImage};
    let mut specs = vec![
        ChannelSpec::of::<TactileRaw>(),
        ChannelSpec::of::<TactileTare>(),
        ChannelSpec::of::<TactileZeroed>(),
        ChannelSpec::of::<TactileDecoder>(),
        ChannelSpec::of::<TactileCalibrated>(),
        ChannelSpec::of::<TactileReference>(),
        ChannelSpec::of::<TactileDeviceTime>(),
        ChannelSpec::of::<GraspControl>(),
        ChannelSpec::of::<HandCommand>(),
        ChannelSpec::of::<GripperCommand>(),
        ChannelSpec::of::<HandState>(),
        ChannelSpec::of::<CompressedImage>(),
        ChannelSpec::of::<CameraCalibration>(),
        ChannelSpec::of::<ArucoDetection>(),
        ChannelSpec::of::<SimTruth>(),
        ChannelSpec::of::<super::ground_truth::GroundTruthSliding>(),
        ChannelSpec::of::<super::ground_truth::GroundTruthMeasurement>(),
        ChannelSpec::of::<super::in_hand::GroundTruthPose>(),
        ChannelSpec::of::<super::in_hand::GroundTruthPlanar>(),
        ChannelSpec::of::<super::estimates::TactileDerivative>(),
        ChannelSpec::of::<super::estimates::DekfEstimate>(),
        ChannelSpec::of::<super::in_hand::PlanarEstimate>(),
        ChannelSpec::of::<super::in_hand::SlipEstimate>(),
        ChannelSpec::of::<super::estimates::ArucoEstimate>(),
        ChannelSpec::of::<ProtocolEvent>(),
        ChannelSpec::of::<RecorderStats>(),
    ]
    .into_iter()
    .chain(super::vision_pose::vision_channel_specs())
    .collect::<Vec<_>>();
    // `/rgbd/depth` after `/rgbd/color`, as in the docs.
    let color = specs.iter().position(|s| s.topic == "/rgbd/color").map_or(specs.len(), |k| k + 1);
    specs.insert(color, ChannelSpec::of::<super::depth::RgbdDepth>());
    specs
}

/// Three components along the x, y and z axes of a tactile module's frame.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct Xyz<T> {
    /// Along x.
    pub x: T,
    /// Along y.
    pub y: T,
    /// Along z (normal to the fingertip surface).
    pub z: T,
}

impl<T: Copy> Xyz<T> {
    /// From `[x, y, z]`.
    pub fn from_array([x, y, z]: [T; 3]) -> Xyz<T> {
        Xyz { x, y, z }
    }

    /// As `[x, y, z]`.
    pub fn to_array(self) -> [T; 3] {
        [self.x, self.y, self.z]
    }
}

/// The values of one sensor's taxels.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct SensorValues<T> {
    /// The sensor's name in the tactile layout.
    pub name: String,
    /// One value per taxel, in the layout's taxel order (row by row).
    pub taxels: Vec<Xyz<T>>,
}

/// Values of every taxel of every sensor, sensors in layout order:
/// `[{"name": "thumb", "taxels": [{"x": .., "y": .., "z": ..}, ..]}, ..]`.
pub type SensorTaxels<T> = Vec<SensorValues<T>>;

/// Splits a scan (`[taxel][x, y, z]` in layout order) into its sensors.
pub fn sensor_taxels<T: Copy>(layout: &TactileLayout, scan: &[[T; 3]]) -> SensorTaxels<T> {
    layout
        .sensor_ranges()
        .map(|(sensor, range)| SensorValues {
            name: sensor.name.clone(),
            taxels: scan.get(range).unwrap_or(&[]).iter().map(|v| Xyz::from_array(*v)).collect(),
        })
        .collect()
}

/// Joins per-sensor values back into a scan in layout order; an error
/// names the sensor that is missing or has the wrong number of taxels.
pub fn scan_of<T: Copy>(
    layout: &TactileLayout,
    sensors: &[SensorValues<T>],
) -> Result<Vec<[T; 3]>, LayoutError> {
    let mut scan = Vec::with_capacity(layout.taxel_count());
    for sensor in &layout.sensors {
        let taxels = sensors.iter().find(|s| s.name == sensor.name).map_or(&[][..], |s| s.taxels.as_slice());
        if taxels.len() != sensor.taxels() {
            return Err(LayoutError::SensorSize {
                name: sensor.name.clone(),
                expected: sensor.taxels(),
                got: taxels.len(),
            });
        }
        scan.extend(taxels.iter().map(|v| v.to_array()));
    }
    Ok(scan)
}

/// `/tactile/raw`: one scan of every taxel of every tactile sensor, raw
/// counts as the device sent them (never tared, never overwritten).
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct TactileRaw {
    /// The device's own scan counter.
    pub sequence: u64,
    /// Raw counts (0-65535) of every taxel, per sensor in layout order
    /// (names and taxel grids in the channel's [`TaxelLayout`]).
    pub sensors: SensorTaxels<u16>,
}

impl TactileRaw {
    /// The message of `sample`, a scan of `layout`.
    pub fn new(sample: &TactileSample, layout: &TactileLayout) -> TactileRaw {
        TactileRaw { sequence: sample.sequence, sensors: sensor_taxels(layout, &sample.raw) }
    }

    /// The scan (raw counts of every taxel in `layout` order).
    pub fn scan(&self, layout: &TactileLayout) -> Result<Vec<RawTaxel>, LayoutError> {
        scan_of(layout, &self.sensors)
    }
}

impl ChannelMessage for TactileRaw {
    const TOPIC: &'static str = "/tactile/raw";
    const SCHEMA_NAME: &'static str = "slidetrack.TactileRaw";
    fn json_schema() -> Value {
        derived::<Self>(Self::SCHEMA_NAME)
    }
}

/// Channel metadata key of `/tactile/raw` (and session metadata key) holding
/// the [`TaxelLayout`] as JSON.
pub const TAXEL_LAYOUT_KEY: &str = "taxel_layout";

/// The layout of the tactile channels, stored as JSON in the `/tactile/raw`
/// channel metadata and in the session metadata under [`TAXEL_LAYOUT_KEY`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TaxelLayout {
    /// The device that produced the counts (`sim`, `/dev/ttyACM0`, `can0`).
    pub device: String,
    /// Nominal scan rate (Hz).
    pub rate_hz: f64,
    /// Axis names of each taxel, in the order of raw arrays.
    pub axes: Vec<String>,
    /// The sensors, in scan order: name, model, finger, taxel grid.
    pub sensors: Vec<SensorLayout>,
    /// What each finger's reading (the controller's z, the `finger.axis`
    /// dEKF channels) is made of.
    pub fingers: PerFinger<FingerReading>,
}

impl TaxelLayout {
    /// The layout of `info`'s device.
    pub fn new(info: &TactileInfo) -> TaxelLayout {
        TaxelLayout {
            device: info.device.clone(),
            rate_hz: info.rate_hz,
            axes: slidetrack_core::AXES.iter().map(|a| a.to_string()).collect(),
            sensors: info.layout.sensors.clone(),
            fingers: info.fingers.clone(),
        }
    }

    /// The tactile source this layout describes.
    pub fn info(&self) -> TactileInfo {
        TactileInfo {
            device: self.device.clone(),
            rate_hz: self.rate_hz,
            layout: TactileLayout { sensors: self.sensors.clone() },
            fingers: self.fingers.clone(),
        }
    }

    /// As JSON.
    pub fn to_json(&self) -> String {
        // Serializing plain strings and numbers to a String cannot fail.
        serde_json::to_string(self).unwrap_or_default()
    }

    /// The channel metadata map holding this layout.
    pub fn channel_metadata(&self) -> BTreeMap<String, String> {
        BTreeMap::from([(TAXEL_LAYOUT_KEY.to_string(), self.to_json())])
    }

    /// The layout stored in channel (or session) metadata: `None` without
    /// the key, an error when its JSON does not decode.
    pub fn from_channel_metadata(
        metadata: &BTreeMap<String, String>,
    ) -> Option<Result<TaxelLayout, serde_json::Error>> {
        metadata.get(TAXEL_LAYOUT_KEY).map(|s| serde_json::from_str(s))
    }
}

/// `/tactile/tare`: the baseline was (re)zeroed. Later `/tactile/zeroed`
/// messages subtract this baseline.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct TactileTare {
    /// Scans averaged into the baseline.
    pub samples: u32,
    /// Baseline of every taxel, per sensor in layout order: the mean raw value (counts).
    pub baseline: SensorTaxels<f64>,
}

impl ChannelMessage for TactileTare {
    const TOPIC: &'static str = "/tactile/tare";
    const SCHEMA_NAME: &'static str = "slidetrack.TactileTare";
    fn json_schema() -> Value {
        derived::<Self>(Self::SCHEMA_NAME)
    }
}

/// `/tactile/zeroed`: one scan minus the current baseline (counts), every
/// taxel, per sensor.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct TactileZeroed {
    /// Counts minus baseline of every taxel, per sensor in layout order.
    pub sensors: SensorTaxels<f64>,
}

impl ChannelMessage for TactileZeroed {
    const TOPIC: &'static str = "/tactile/zeroed";
    const SCHEMA_NAME: &'static str = "slidetrack.TactileZeroed";
    fn json_schema() -> Value {
        derived::<Self>(Self::SCHEMA_NAME)
    }
}

/// `/tactile/decoder`: the counters of the tactile device's decoder (real
/// rigs and decoded captures) since the device was opened.
///
/// The same counters as `slidetrack_core::DecoderCounters`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct TactileDecoder {
    /// Frames decoded intact.
    pub frames: u64,
    /// Frames that arrived in sync but failed their CRC.
    pub crc_errors: u64,
    /// Times the decoder lost the frame boundaries and found them again.
    pub resyncs: u64,
    /// Bytes discarded while resynchronising.
    pub bytes_skipped: u64,
    /// Breaks in a module's sequence counter.
    pub gaps: u64,
    /// Scans dropped because a frame (or a mapped taxel) was missing.
    pub incomplete_scans: u64,
    /// Taxel samples the sensor marked invalid.
    pub invalid_samples: u64,
}

impl From<&slidetrack_core::DecoderCounters> for TactileDecoder {
    fn from(c: &slidetrack_core::DecoderCounters) -> TactileDecoder {
        TactileDecoder {
            frames: c.frames,
            crc_errors: c.crc_errors,
            resyncs: c.resyncs,
            bytes_skipped: c.bytes_skipped,
            gaps: c.gaps,
            incomplete_scans: c.incomplete_scans,
            invalid_samples: c.invalid_samples,
        }
    }
}

impl ChannelMessage for TactileDecoder {
    const TOPIC: &'static str = "/tactile/decoder";
    const SCHEMA_NAME: &'static str = "slidetrack.TactileDecoder";
    fn json_schema() -> Value {
        derived::<Self>(Self::SCHEMA_NAME)
    }
}

/// `/tactile/calibrated`: the forces a device computed from one scan
/// (`xela_server` with its force calibration on), every taxel of every
/// sensor, in newtons. Written only for scans that carry them, at the
/// `log_time` of their `/tactile/raw` message.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct TactileCalibrated {
    /// The device's scan counter, as in `/tactile/raw`.
    pub sequence: u64,
    /// Force on every taxel (N), per sensor in layout order, in the
    /// sensor's frame as the device reports it.
    pub sensors: SensorTaxels<f64>,
}

impl TactileCalibrated {
    /// The message of `sample`, a scan of `layout`, if it carries forces.
    pub fn new(sample: &TactileSample, layout: &TactileLayout) -> Option<TactileCalibrated> {
        let forces = sample.calibrated_n.as_ref()?;
        Some(TactileCalibrated { sequence: sample.sequence, sensors: sensor_taxels(layout, forces) })
    }
}

impl ChannelMessage for TactileCalibrated {
    const TOPIC: &'static str = "/tactile/calibrated";
    const SCHEMA_NAME: &'static str = "slidetrack.TactileCalibrated";
    fn json_schema() -> Value {
        derived::<Self>(Self::SCHEMA_NAME)
    }
}

/// `/tactile/reference`: the reference force on every taxel of one scan
/// (N, in each taxel's frame), the target `slidetrack calibrate tactile`
/// fits counts to. The simulated rig writes it with `[sim] reference_forces
/// = true`, at the `log_time` of the scan's `/tactile/raw` message; a real
/// rig's reference (a force-torque sensor under the patch, known weights)
/// is written in the same form by whoever records it.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct TactileReference {
    /// The scan counter, as in `/tactile/raw`.
    pub sequence: u64,
    /// Force on every taxel (N), per sensor in layout order, in each taxel's frame.
    pub sensors: SensorTaxels<f64>,
}

impl TactileReference {
    /// The message of `sample`, a scan of `layout`, if it carries reference forces.
    pub fn new(sample: &TactileSample, layout: &TactileLayout) -> Option<TactileReference> {
        let forces = sample.reference_n.as_ref()?;
        Some(TactileReference { sequence: sample.sequence, sensors: sensor_taxels(layout, forces) })
    }
}

impl ChannelMessage for TactileReference {
    const TOPIC: &'static str = "/tactile/reference";
    const SCHEMA_NAME: &'static str = "slidetrack.TactileReference";
    fn json_schema() -> Value {
        derived::<Self>(Self::SCHEMA_NAME)
    }
}

/// `/tactile/device_time`: the device's own time stamp of a scan, for
/// devices that send one (`xela_server`'s `time`), at the `log_time` of the
/// scan's `/tactile/raw` message (its arrival on the session clock).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct TactileDeviceTime {
    /// The device's scan counter, as in `/tactile/raw`.
    pub sequence: u64,
    /// The device's time stamp (s, on the device's clock: Unix time for `xela_server`).
    pub device_time_s: f64,
}

impl TactileDeviceTime {
    /// The message of `sample`, if it carries a device time stamp.
    pub fn new(sample: &TactileSample) -> Option<TactileDeviceTime> {
        sample
            .device_time_s
            .map(|device_time_s| TactileDeviceTime { sequence: sample.sequence, device_time_s })
    }
}

impl ChannelMessage for TactileDeviceTime {
    const TOPIC: &'static str = "/tactile/device_time";
    const SCHEMA_NAME: &'static str = "slidetrack.TactileDeviceTime";
    fn json_schema() -> Value {
        derived::<Self>(Self::SCHEMA_NAME)
    }
}

/// Desired and achieved baseline-subtracted normal (z) value of one finger (counts).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct FingerSetpoint {
    /// What the controller asks for (counts).
    pub desired: f64,
    /// What the sensor measured (counts).
    pub achieved: f64,
}

/// `/control/grasp`: one step of the grasp controller.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[schemars(transform = describe_fingers("{finger}: baseline-subtracted z, desired and achieved (counts)"))]
pub struct GraspControl {
    /// The protocol's phase (`zero`, `close`, `ramp`, `settle`, `cycles`, ...).
    #[schemars(with = "PhaseName")]
    pub phase: Phase,
    /// The generalised grasp strength reference tau_g,des (counts).
    pub reference: f64,
    /// Desired and achieved z per finger (counts, baseline subtracted).
    #[serde(flatten)]
    #[schemars(with = "Fingers<FingerSetpoint>")]
    pub fingers: PerFinger<FingerSetpoint>,
}

impl ChannelMessage for GraspControl {
    const TOPIC: &'static str = "/control/grasp";
    const SCHEMA_NAME: &'static str = "slidetrack.GraspControl";
    fn json_schema() -> Value {
        derived::<Self>(Self::SCHEMA_NAME)
    }
}

/// `/hand/command`: the voltages sent to the hand.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[schemars(transform = describe_fingers("{finger} command voltage (V)"))]
pub struct HandCommand {
    /// Command per finger (V).
    #[serde(flatten)]
    #[schemars(with = "Fingers<f64>")]
    pub volts: PerFinger<f64>,
    /// True when a command was clipped to the actuator's range.
    pub saturated: bool,
}

impl ChannelMessage for HandCommand {
    const TOPIC: &'static str = "/hand/command";
    const SCHEMA_NAME: &'static str = "slidetrack.HandCommand";
    fn json_schema() -> Value {
        derived::<Self>(Self::SCHEMA_NAME)
    }
}

/// `/hand/gripper`: the position requests sent to a gripper.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct GripperCommand {
    /// Requested closure (steps; 0 = fully open; Robotiq `rPR`).
    pub position: u16,
    /// Speed request (0-255; Robotiq `rSP`).
    pub speed: u8,
    /// Force request (0-255; Robotiq `rFR`).
    pub force: u8,
    /// True when the request was clamped to the gripper's range.
    pub clamped: bool,
}

impl ChannelMessage for GripperCommand {
    const TOPIC: &'static str = "/hand/gripper";
    const SCHEMA_NAME: &'static str = "slidetrack.GripperCommand";
    fn json_schema() -> Value {
        derived::<Self>(Self::SCHEMA_NAME)
    }
}

/// `/hand/state`: what the hand or gripper reports about itself.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct HandState {
    /// Each finger's travel from its open rest position towards the object
    /// (m), in the hand's finger order; empty when the hand does not report it.
    pub finger_travel: Vec<f64>,
    /// Opening between the fingertips (m), for grippers that report it;
    /// `null` for hands that do not.
    pub opening: Option<f64>,
    /// A gripper's status registers, for grippers that report them; `null`
    /// for other hands (and absent in sessions recorded before it existed).
    #[serde(default)]
    pub gripper: Option<GripperState>,
}

/// A gripper's status registers (Robotiq: from `0x07D0`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct GripperState {
    /// Activated and ready (`gSTA = 3`).
    pub activated: bool,
    /// Object detection (`gOBJ`): 0 moving, 1 stopped by a contact while
    /// opening, 2 stopped by a contact while closing (object held), 3 at the
    /// requested position without an object (none, or lost).
    pub object: u8,
    /// Fault code (`gFLT`), 0 when none.
    pub fault: u8,
    /// Position request being followed (`gPR`, steps).
    pub requested: u16,
    /// Finger position (`gPO`, steps, 0 = open).
    pub position: u16,
    /// Motor current (mA).
    pub current_ma: u32,
}

impl HandState {
    /// The message of a hand's status.
    pub fn new(status: &slidetrack_core::HandStatus) -> HandState {
        let gripper = status.gripper.map(|g| GripperState {
            activated: g.activated,
            object: g.object as u8,
            fault: g.fault,
            requested: g.requested_steps,
            position: g.position_steps,
            current_ma: g.current_ma,
        });
        HandState { finger_travel: status.finger_travel_m.clone(), opening: status.opening_m, gripper }
    }
}

impl ChannelMessage for HandState {
    const TOPIC: &'static str = "/hand/state";
    const SCHEMA_NAME: &'static str = "slidetrack.HandState";
    fn json_schema() -> Value {
        derived::<Self>(Self::SCHEMA_NAME)
    }
}

/// `/sim/truth`: the simulator's ground truth (simulated sessions only).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct SimTruth {
    /// Object position along the sliding axis (m).
    pub position: f64,
    /// Object velocity along the sliding axis (m/s).
    pub velocity: f64,
    /// True while the object slides relative to the fingers.
    pub sliding: bool,
    /// True while the object rests on its support.
    pub supported: bool,
    /// Normal force per finger (N).
    #[schemars(with = "Fingers<f64>")]
    pub normal_force: PerFinger<f64>,
    /// Friction force per finger along the sliding axis (N).
    #[schemars(with = "Fingers<f64>")]
    pub friction_force: PerFinger<f64>,
}

impl ChannelMessage for SimTruth {
    const TOPIC: &'static str = "/sim/truth";
    const SCHEMA_NAME: &'static str = "slidetrack.SimTruth";
    fn json_schema() -> Value {
        derived::<Self>(Self::SCHEMA_NAME)
    }
}

/// `/protocol/events`: a step of the trial protocol, or an abort.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct ProtocolEvent {
    /// The protocol phase entered or running.
    #[schemars(with = "PhaseName")]
    pub phase: Phase,
    /// What happened, for people.
    pub message: String,
    /// True when this event aborts the trial.
    pub abort: bool,
}

impl ProtocolEvent {
    /// True for the event that ends the sliding cycles: the release, or an abort.
    pub fn ends_cycles(&self) -> bool {
        self.phase == Phase::Release || self.abort
    }
}

impl ChannelMessage for ProtocolEvent {
    const TOPIC: &'static str = "/protocol/events";
    const SCHEMA_NAME: &'static str = "slidetrack.ProtocolEvent";
    fn json_schema() -> Value {
        derived::<Self>(Self::SCHEMA_NAME)
    }
}

/// `/recorder/stats`: written once by the recorder when it finishes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct RecorderStats {
    /// Messages written before this one.
    pub messages_written: u64,
    /// Images dropped because the recorder's queue was full.
    pub images_dropped: u64,
}

impl ChannelMessage for RecorderStats {
    const TOPIC: &'static str = "/recorder/stats";
    const SCHEMA_NAME: &'static str = "slidetrack.RecorderStats";
    fn json_schema() -> Value {
        derived::<Self>(Self::SCHEMA_NAME)
    }
}
