//! The channels a rewrite adds, what it reports, and the writer of the
//! rewritten file.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufWriter;

use serde::Serialize;
use slidetrack_core::TimeNs;

use crate::channel::{ChannelMessage, MESSAGE_ENCODING_JSON, SCHEMA_ENCODING_JSONSCHEMA};

/// A message of a channel added by [`rewrite_session`](crate::rewrite_session).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct NewMessage {
    /// Log time on the session clock.
    pub log_time: TimeNs,
    /// Publish time (the log time when there is no device time).
    pub publish_time: TimeNs,
    /// Sequence number.
    pub sequence: u32,
    /// The payload.
    pub data: Vec<u8>,
}

/// A channel added by [`rewrite_session`](crate::rewrite_session), with all its messages.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct NewChannel {
    /// Topic; an existing channel on it is replaced.
    pub topic: String,
    /// Schema name (empty with `schema_encoding` for no schema).
    pub schema_name: String,
    /// Schema encoding.
    pub schema_encoding: String,
    /// Schema bytes.
    pub schema: Vec<u8>,
    /// Message encoding.
    pub message_encoding: String,
    /// Channel metadata.
    pub metadata: BTreeMap<String, String>,
    /// The messages, in log-time order (sorted stably before writing).
    pub messages: Vec<NewMessage>,
}

impl NewChannel {
    /// An empty channel for `T` (JSON messages, JSON Schema).
    pub fn of<T: ChannelMessage>(metadata: BTreeMap<String, String>) -> NewChannel {
        NewChannel {
            topic: T::TOPIC.to_string(),
            schema_name: T::SCHEMA_NAME.to_string(),
            schema_encoding: SCHEMA_ENCODING_JSONSCHEMA.to_string(),
            schema: T::json_schema().to_string().into_bytes(),
            message_encoding: MESSAGE_ENCODING_JSON.to_string(),
            metadata,
            messages: Vec::new(),
        }
    }

    /// Appends `message` as JSON at `log_time` (also its publish time, sequence 0).
    pub fn push_json<T: Serialize>(
        &mut self,
        log_time: TimeNs,
        message: &T,
    ) -> Result<(), serde_json::Error> {
        let data = serde_json::to_vec(message)?;
        self.messages.push(NewMessage { log_time, publish_time: log_time, sequence: 0, data });
        Ok(())
    }
}

/// What a rewrite did.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct RewriteReport {
    /// Messages copied unchanged.
    pub messages_copied: u64,
    /// Messages of replaced channels left out.
    pub messages_dropped: u64,
    /// Messages of the new channels written.
    pub messages_added: u64,
    /// The input was truncated and only its complete chunks were kept (with `recover`).
    pub truncated: bool,
}

/// The writer of the rewritten file.
pub(super) type Writer<'a> = mcap::Writer<BufWriter<&'a File>>;
