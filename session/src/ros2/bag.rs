//! [`export_ros2_bag`]: a session as a ROS 2 bag in MCAP.
//!
//! The bag follows the MCAP format registry's `ros2` profile: header
//! profile `ros2`, every channel with message encoding `cdr` and the
//! `offered_qos_profiles` metadata, every schema of encoding `ros2msg` named
//! `pkg/msg/Type` holding its complete definition (see `definitions.rs`).
//! Messages keep their log and publish times (session clock, ns from the
//! start of the session) and their sequence numbers; their contents are
//! converted as `convert.rs` says.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufWriter;
use std::path::Path;

use mcap::records::MessageHeader;

use super::convert::convert;
use super::definitions::complete_definition;
use crate::error::{SessionError, WriteFailure};
use crate::reader::{MessageReader, ReadOptions};

/// The QoS every channel was offered with, as rosbag2 writes it: ROS 2's
/// default profile (keep last 10, reliable, volatile, no deadline,
/// lifespan or lease).
const OFFERED_QOS_PROFILES: &str = "- history: keep_last\n  depth: 10\n  reliability: reliable\n  \
     durability: volatile\n  deadline:\n    sec: 0\n    nsec: 0\n  lifespan:\n    sec: 0\n    nsec: 0\n  \
     liveliness: automatic\n  liveliness_lease_duration:\n    sec: 0\n    nsec: 0\n  \
     avoid_ros_namespace_conventions: false\n";

/// What [`export_ros2_bag`] wrote and left out.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Ros2BagReport {
    /// Messages written, per bag topic.
    pub written: BTreeMap<String, u64>,
    /// Messages left out (no ROS 2 counterpart), per session topic.
    pub left_out: BTreeMap<String, u64>,
}

/// Writes the messages of the session at `session` as a ROS 2 bag (MCAP,
/// CDR) to `out`. Errors name the file: the session unreadable, a message
/// that does not decode as its schema, `out` not writable.
pub fn export_ros2_bag(
    session: &Path,
    out: &Path,
    options: ReadOptions,
) -> Result<Ros2BagReport, SessionError> {
    let reader = MessageReader::open(session, &[], options)?;
    let file =
        File::create(out).map_err(|source| SessionError::Create { path: out.to_path_buf(), source })?;
    let fail = |e: mcap::McapError| {
        let source = WriteFailure::from(e);
        SessionError::Write { path: out.to_path_buf(), kind: source.io_kind(), source }
    };
    let write_options = mcap::WriteOptions::new()
        .compression(Some(mcap::Compression::Zstd))
        .compression_level(1)
        .compression_threads(0)
        .profile("ros2")
        .library(concat!("slidetrack ", env!("CARGO_PKG_VERSION")));
    let mut writer =
        mcap::Writer::with_options(BufWriter::with_capacity(256 << 10, file), write_options).map_err(fail)?;
    let mut schemas: BTreeMap<&'static str, u16> = BTreeMap::new();
    let mut channels: BTreeMap<String, u16> = BTreeMap::new();
    let metadata = BTreeMap::from([("offered_qos_profiles".to_string(), OFFERED_QOS_PROFILES.to_string())]);
    let mut report = Ros2BagReport::default();
    for message in reader {
        let message = message?;
        let (schema, topic) = (message.channel.schema_name.as_str(), message.channel.topic.as_str());
        let converted = convert(schema, topic, message.log_time, &message.data).map_err(|source| {
            SessionError::Decode {
                path: session.to_path_buf(),
                topic: topic.to_string(),
                log_time: message.log_time,
                source,
            }
        })?;
        let Some(ros) = converted else {
            *report.left_out.entry(topic.to_string()).or_default() += 1;
            continue;
        };
        let schema_id = match schemas.get(ros.ros_type) {
            Some(id) => *id,
            None => {
                let text = complete_definition(ros.ros_type).expect("every converted type has a definition");
                let id = writer.add_schema(ros.ros_type, "ros2msg", text.as_bytes()).map_err(fail)?;
                *schemas.entry(ros.ros_type).or_insert(id)
            }
        };
        let channel_id = match channels.get(&ros.topic) {
            Some(id) => *id,
            None => {
                let id = writer.add_channel(schema_id, &ros.topic, "cdr", &metadata).map_err(fail)?;
                *channels.entry(ros.topic.clone()).or_insert(id)
            }
        };
        let header = MessageHeader {
            channel_id,
            sequence: message.sequence,
            log_time: message.log_time.0,
            publish_time: message.publish_time.0,
        };
        writer.write_to_known_channel(&header, &ros.data).map_err(fail)?;
        *report.written.entry(ros.topic).or_default() += 1;
    }
    writer.finish().map_err(fail)?;
    let buffered = writer.into_inner();
    buffered.into_inner().map_err(|e| fail(mcap::McapError::Io(e.into_error())))?;
    Ok(report)
}
