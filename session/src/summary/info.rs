//! What a session holds ([`SessionInfo`], [`ChannelSummary`]) and the
//! parts it is assembled from, by the summary section's fast path or by a
//! scan.

use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};
use std::time::Duration;

use slidetrack_core::TimeNs;

use crate::stored::{AttachmentSummary, ChannelDesc};

/// One channel of a session.
#[derive(Clone, Debug, PartialEq)]
pub struct ChannelSummary {
    /// The channel's topic.
    pub topic: String,
    /// Schema name (`slidetrack.TactileRaw`), empty when there is none.
    pub schema_name: String,
    /// Message encoding (`json`).
    pub message_encoding: String,
    /// Channel metadata.
    pub metadata: BTreeMap<String, String>,
    /// Messages on the channel.
    pub message_count: u64,
    /// Log time of its first message.
    pub first_log_time: Option<TimeNs>,
    /// Log time of its last message.
    pub last_log_time: Option<TimeNs>,
    /// `(count - 1) / (last - first)` (Hz), `None` with fewer than two
    /// messages or no time between them.
    pub mean_rate_hz: Option<f64>,
}

/// What a session file holds.
#[derive(Clone, Debug, PartialEq)]
pub struct SessionInfo {
    /// The file.
    pub path: PathBuf,
    /// Its size (bytes).
    pub file_size_bytes: u64,
    /// Channels, by channel id.
    pub channels: Vec<ChannelSummary>,
    /// Messages on all channels.
    pub message_count: u64,
    /// Log time of the first message.
    pub start: Option<TimeNs>,
    /// Log time of the last message.
    pub end: Option<TimeNs>,
    /// `end - start`.
    pub duration: Duration,
    /// Metadata records by name (the last one wins when a name repeats).
    pub metadata: BTreeMap<String, BTreeMap<String, String>>,
    /// Attachments, in file order.
    pub attachments: Vec<AttachmentSummary>,
    /// Complete chunks.
    pub chunk_count: u64,
    /// True when the file was cut short (read with `recover`): everything
    /// above describes its complete chunks only.
    pub truncated: bool,
}

/// Per-channel counts and times, filled while reading.
#[derive(Default)]
pub(super) struct ChannelTally {
    pub(super) count: u64,
    pub(super) first: Option<TimeNs>,
    pub(super) last: Option<TimeNs>,
}

impl ChannelTally {
    pub(super) fn add(&mut self, t: TimeNs) {
        self.count += 1;
        self.first = Some(self.first.map_or(t, |f| f.min(t)));
        self.last = Some(self.last.map_or(t, |l| l.max(t)));
    }
}

fn channel_summary(desc: &ChannelDesc, tally: Option<&ChannelTally>) -> ChannelSummary {
    let (count, first, last) = tally.map_or((0, None, None), |t| (t.count, t.first, t.last));
    let mean_rate_hz = match (first, last) {
        (Some(f), Some(l)) if count >= 2 && l > f => Some((count - 1) as f64 / l.secs_since(f)),
        _ => None,
    };
    ChannelSummary {
        topic: desc.topic.clone(),
        schema_name: desc.schema_name.clone(),
        message_encoding: desc.message_encoding.clone(),
        metadata: desc.metadata.clone(),
        message_count: count,
        first_log_time: first,
        last_log_time: last,
        mean_rate_hz,
    }
}

/// What a [`SessionInfo`] is made of, read from the summary section or by a scan.
pub(super) struct Parts {
    /// Channels, by id.
    pub(super) channels: Vec<ChannelDesc>,
    /// Counts and times per channel id.
    pub(super) tallies: HashMap<u16, ChannelTally>,
    /// Metadata records by name.
    pub(super) metadata: BTreeMap<String, BTreeMap<String, String>>,
    /// Attachments, in file order.
    pub(super) attachments: Vec<AttachmentSummary>,
    /// Complete chunks.
    pub(super) chunk_count: u64,
}

impl Parts {
    pub(super) fn assemble(self, path: &Path, file_size_bytes: u64, truncated: bool) -> SessionInfo {
        let tallies = &self.tallies;
        let channels: Vec<ChannelSummary> =
            self.channels.iter().map(|c| channel_summary(c, tallies.get(&c.id))).collect();
        let start = channels.iter().filter_map(|c| c.first_log_time).min();
        let end = channels.iter().filter_map(|c| c.last_log_time).max();
        let duration = match (start, end) {
            (Some(s), Some(e)) => e - s,
            _ => Duration::ZERO,
        };
        SessionInfo {
            path: path.to_path_buf(),
            file_size_bytes,
            message_count: channels.iter().map(|c| c.message_count).sum(),
            channels,
            start,
            end,
            duration,
            metadata: self.metadata,
            attachments: self.attachments,
            chunk_count: self.chunk_count,
            truncated,
        }
    }
}
