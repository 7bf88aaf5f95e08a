#![doc = include_str!("../README.md")]
#![warn(missing_docs)]
//!
//! - [`Recorder`] writes a session on its own thread (zstd chunks closed at
//!   least every second, so a killed process leaves a readable prefix).
//! - [`SessionInfo`], [`MessageReader`] and [`read_json`] read one back with
//!   bounded memory; [`export_csv`] flattens a channel to CSV, and
//!   [`export_ros2_bag`] writes a session as a ROS 2 bag. The
//!   `from_reader` variants read a session from memory (any `Read + Seek`).
//! - The message types of the channels are in [`messages`] and [`vision`];
//!   the format is documented in `docs/session-format.md`.

mod channel;
mod csv;
pub mod depth;
mod error;
pub mod estimates;
pub mod ground_truth;
pub mod in_hand;
mod live;
pub mod messages;
mod metadata;
pub mod odometry;
mod reader;
mod recorder;
mod records;
mod rewrite;
pub mod ros2;
mod scan;
mod schema;
mod shared;
mod stored;
mod summary;
pub mod vision;
pub mod vision_pose;
mod writer;
mod writer_thread;

#[cfg(test)]
mod tests;

pub use csv::{CsvSummary, export_csv, export_csv_from_reader};
pub use depth::{DepthCodecError, RgbdDepth};
pub use error::{Corruption, ReplaceStep, SessionError, WriteFailure};
pub use estimates::{
    ArucoEstimate, DERIVATIVE_CHANNELS_KEY, DekfEstimate, SlidingEstimate, TactileDerivative,
};
pub use ground_truth::{GroundTruthMeasurement, GroundTruthParameters, GroundTruthSliding};
pub use in_hand::{
    GraspStateName, GroundTruthPlanar, GroundTruthPose, PlanarEstimate, PlanarState, SlipEstimate,
};
pub use live::{LiveChannel, LiveReceiver, LiveRecord, LiveSession, LiveTap, LiveTapStats, TapClosed};
pub use messages::{
    ChannelMessage, ChannelSpec, FingerSetpoint, GraspControl, GripperCommand, GripperState, HandCommand,
    HandState, ProtocolEvent, RecorderStats, SensorTaxels, SensorValues, SimTruth, TAXEL_LAYOUT_KEY,
    TactileCalibrated, TactileDecoder, TactileDeviceTime, TactileRaw, TactileReference, TactileTare,
    TactileZeroed, TaxelLayout, Xyz, channel_specs, scan_of, sensor_taxels,
};
pub use metadata::{OUTCOME_METADATA, SESSION_METADATA, SessionMetadata, SessionOutcome};
pub use odometry::{MaskUkfOdometry, Odometry, RoftOdometry};
pub use reader::{MessageReader, ReadOptions, read_channel, read_json, release_time};
pub use recorder::Recorder;
pub use rewrite::{NewChannel, NewMessage, RewriteReport, rewrite_session};
pub use ros2::{Ros2BagReport, export_ros2_bag};
pub use schema::JSON_SCHEMA_DIALECT;
pub use stored::{AttachmentSummary, ChannelDesc, RawMessage};
pub use summary::{ChannelSummary, SessionInfo};
pub use vision::{ArucoDetection, CameraCalibration, CompressedImage, FoxgloveTime, Quaternion};
pub use vision_pose::{
    FrameTransform, ObjectTruth, PoseInFrame, RawImage, RgbdCalibration, RgbdColor, RgbdMask,
    VelocityEstimate, VisionMask, VisionPose,
};
pub use writer::{ChannelHandle, Logger, PendingPayload, RecorderOptions, Untyped};
pub use writer_thread::SessionSink;
