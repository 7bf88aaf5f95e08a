//! The new channels of a rewrite, merged by log time among the copied messages.

use std::path::Path;

use mcap::records::MessageHeader;
use slidetrack_core::TimeNs;

use super::survey::Survey;
use super::types::{NewChannel, Writer};
use crate::error::SessionError;

/// The new channels, written in log-time order among the copied messages.
pub(super) struct Merge {
    channels: Vec<(NewChannel, u16, u16, bool)>,
    /// Next message per channel.
    cursor: Vec<usize>,
}

impl Merge {
    pub(super) fn new(path: &Path, add: Vec<NewChannel>, survey: &Survey) -> Result<Merge, SessionError> {
        let mut channels = Vec::with_capacity(add.len());
        for (k, channel) in add.into_iter().enumerate() {
            let k = k as u32;
            let schema_id = u16::try_from(survey.next_schema_id + k);
            let channel_id = u16::try_from(survey.next_channel_id + k);
            let (Ok(schema_id), Ok(channel_id)) = (schema_id, channel_id) else {
                return Err(SessionError::Channel {
                    path: path.to_path_buf(),
                    topic: channel.topic,
                    detail: "no free schema or channel id".into(),
                });
            };
            channels.push((channel, schema_id, channel_id, false));
        }
        let cursor = vec![0; channels.len()];
        Ok(Merge { channels, cursor })
    }

    /// Writes every pending new message with a log time before `t`, oldest
    /// first (ties in the order of the channels); returns how many.
    pub(super) fn write_before(&mut self, w: &mut Writer<'_>, t: TimeNs) -> Result<u64, mcap::McapError> {
        let mut written = 0;
        loop {
            let next = (0..self.channels.len())
                .filter_map(|k| self.channels[k].0.messages.get(self.cursor[k]).map(|m| (m.log_time, k)))
                .filter(|(log_time, _)| *log_time < t)
                .min();
            let Some((_, k)) = next else { return Ok(written) };
            Self::declare(w, &mut self.channels[k])?;
            let (channel, _, channel_id, _) = &self.channels[k];
            let m = &channel.messages[self.cursor[k]];
            let header = MessageHeader {
                channel_id: *channel_id,
                sequence: m.sequence,
                log_time: m.log_time.0,
                publish_time: m.publish_time.0,
            };
            w.write_to_known_channel(&header, &m.data)?;
            self.cursor[k] += 1;
            written += 1;
        }
    }

    /// Declares the channels that had no message.
    pub(super) fn declare_empty(&mut self, w: &mut Writer<'_>) -> Result<(), mcap::McapError> {
        self.channels.iter_mut().try_for_each(|c| Self::declare(w, c))
    }

    fn declare(w: &mut Writer<'_>, entry: &mut (NewChannel, u16, u16, bool)) -> Result<(), mcap::McapError> {
        let (c, schema_id, channel_id, declared) = entry;
        if !*declared {
            let schema_id = if c.schema_name.is_empty() && c.schema_encoding.is_empty() {
                0
            } else {
                w.add_schema_with_id(*schema_id, &c.schema_name, &c.schema_encoding, &c.schema)?
            };
            w.add_channel_with_id(*channel_id, schema_id, &c.topic, &c.message_encoding, &c.metadata)?;
            *declared = true;
        }
        Ok(())
    }
}
