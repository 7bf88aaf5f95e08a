//! The records of a session file as the readers hand them out: channels,
//! messages and attachments.

use std::collections::BTreeMap;
use std::sync::Arc;

use slidetrack_core::TimeNs;

/// A channel as declared in the file.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ChannelDesc {
    /// The channel id in the file.
    pub id: u16,
    /// The topic, for example `/tactile/raw`.
    pub topic: String,
    /// Schema name, empty when the channel has none.
    pub schema_name: String,
    /// Schema encoding (`jsonschema`), empty when the channel has none.
    pub schema_encoding: String,
    /// Message encoding (`json`).
    pub message_encoding: String,
    /// Channel metadata (the taxel layout on `/tactile/raw`).
    pub metadata: BTreeMap<String, String>,
}

/// One message as stored.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RawMessage {
    /// The channel it was published on.
    pub channel: Arc<ChannelDesc>,
    /// Host acquisition time on the session clock.
    pub log_time: TimeNs,
    /// The device's timestamp, or `log_time` when the device has none.
    pub publish_time: TimeNs,
    /// The device's frame counter (low 32 bits).
    pub sequence: u32,
    /// The payload (JSON for slidetrack's channels).
    pub data: Vec<u8>,
}

impl RawMessage {
    /// The channel's topic.
    pub fn topic(&self) -> &str {
        &self.channel.topic
    }
}

/// An attachment of a session.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct AttachmentSummary {
    /// Its name (a file name).
    pub name: String,
    /// Its media type (`application/toml`).
    pub media_type: String,
    /// Its size (bytes).
    pub size_bytes: u64,
}
