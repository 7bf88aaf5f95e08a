//! The recorder's writer thread: drains the queue into the `mcap::Writer`,
//! closes chunks on time, and stops cleanly at the first write failure.

use std::borrow::Cow;
use std::collections::BTreeMap;
use std::io::{BufWriter, Seek, Write};
use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use crossbeam_channel::{Receiver, RecvTimeoutError};
use mcap::Attachment;
use mcap::records::{MessageHeader, Metadata};
use slidetrack_core::TimeNs;

use super::channel::{ChannelMessage, MESSAGE_ENCODING_JSON, SCHEMA_ENCODING_JSONSCHEMA};
use super::error::{SessionError, WriteFailure};
use super::live::{LiveChannel, LiveSession};
use super::messages::RecorderStats;
use super::metadata::{OUTCOME_METADATA, SessionOutcome};
use super::shared::{ChannelRegistration, Command, Shared};

/// Where a [`Recorder`](super::Recorder) writes: the session file, or any
/// seekable byte sink (a buffer in memory, a file behind a test's gate).
pub trait SessionSink: Write + Seek + Send + 'static {
    /// Makes the bytes written so far durable (`fsync` for a file).
    fn sync(&mut self) -> std::io::Result<()>;
}

impl SessionSink for std::fs::File {
    fn sync(&mut self) -> std::io::Result<()> {
        self.sync_all()
    }
}

impl SessionSink for std::io::Cursor<Vec<u8>> {
    fn sync(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

pub(crate) type McapWriter = mcap::Writer<BufWriter<Box<dyn SessionSink>>>;

pub(crate) struct WriterThread {
    writer: McapWriter,
    rx: Receiver<Command>,
    shared: Arc<Shared>,
    flush_interval: Duration,
    /// When the open chunk got its first record; `None` when no chunk is open.
    chunk_opened_at: Option<Instant>,
    messages_written: u64,
    last_log_time: TimeNs,
    /// Where written records go on to a live viewer.
    live: Option<LiveSession>,
}

impl WriterThread {
    pub(crate) fn new(
        writer: McapWriter,
        rx: Receiver<Command>,
        shared: Arc<Shared>,
        flush_interval: Duration,
        live: Option<LiveSession>,
    ) -> WriterThread {
        WriterThread {
            writer,
            rx,
            shared,
            flush_interval,
            chunk_opened_at: None,
            messages_written: 0,
            last_log_time: TimeNs::ZERO,
            live,
        }
    }

    /// Runs until `Finish` (or until every sender is gone) and returns the stats.
    pub(crate) fn run(mut self) -> Result<RecorderStats, SessionError> {
        loop {
            let deadline = self.chunk_opened_at.and_then(|t| t.checked_add(self.flush_interval));
            let received = match deadline {
                Some(deadline) => self.rx.recv_deadline(deadline),
                None => self.rx.recv().map_err(|_| RecvTimeoutError::Disconnected),
            };
            let step = match received {
                Ok(Command::Finish { stats_channel, outcome }) => {
                    return self.finish(stats_channel, outcome);
                }
                Ok(cmd) => self.handle(cmd),
                Err(RecvTimeoutError::Timeout) => Ok(()),
                Err(RecvTimeoutError::Disconnected) => return self.finish(None, None),
            };
            let step = step.and_then(|()| self.flush_if_due());
            if let Err(failure) = step {
                self.shared.fail(failure);
                return self.drain();
            }
        }
    }

    fn handle(&mut self, cmd: Command) -> Result<(), WriteFailure> {
        match cmd {
            Command::Channel { id, registration: r } => {
                let schema_id = if r.schema_name.is_empty() && r.schema_encoding.is_empty() {
                    0
                } else {
                    self.writer.add_schema(&r.schema_name, &r.schema_encoding, &r.schema_data)?
                };
                self.writer.add_channel_with_id(id, schema_id, &r.topic, &r.message_encoding, &r.metadata)?;
                self.chunk_opened_at.get_or_insert_with(Instant::now);
                if let Some(live) = &self.live {
                    live.channel(id, live_channel(*r));
                }
            }
            Command::Message { channel, log_time, publish_time, sequence, payload, lossy } => {
                if lossy {
                    let len = payload.len();
                    self.shared.lossy_bytes_queued.fetch_sub(len, Ordering::AcqRel);
                }
                self.write_message(channel, log_time, publish_time, sequence, &payload)?;
                if let Some(live) = &mut self.live {
                    live.message(channel, log_time, publish_time, sequence, payload);
                }
            }
            Command::Pending { channel, log_time, publish_time, sequence, payload } => {
                // Its producer dropped it unfilled: the message is not written.
                if let Ok(payload) = payload.recv() {
                    self.write_message(channel, log_time, publish_time, sequence, &payload)?;
                    if let Some(live) = &mut self.live {
                        live.message(channel, log_time, publish_time, sequence, payload);
                    }
                }
            }
            Command::Attachment { name, media_type, data } => {
                let attachment = Attachment {
                    log_time: self.last_log_time.0,
                    create_time: self.last_log_time.0,
                    name,
                    media_type,
                    data: Cow::Owned(data),
                };
                self.writer.attach(&attachment)?;
                self.flush()?;
            }
            Command::Metadata { name, map } => {
                self.writer.write_metadata(&Metadata { name, metadata: map })?;
                self.flush()?;
            }
            Command::Finish { .. } => {}
        }
        Ok(())
    }

    fn write_message(
        &mut self,
        channel: u16,
        log_time: TimeNs,
        publish_time: TimeNs,
        sequence: u32,
        payload: &[u8],
    ) -> Result<(), WriteFailure> {
        let header = MessageHeader {
            channel_id: channel,
            sequence,
            log_time: log_time.0,
            publish_time: publish_time.0,
        };
        self.writer.write_to_known_channel(&header, payload)?;
        self.messages_written += 1;
        self.last_log_time = self.last_log_time.max(log_time);
        self.chunk_opened_at.get_or_insert_with(Instant::now);
        Ok(())
    }

    fn flush_if_due(&mut self) -> Result<(), WriteFailure> {
        match self.chunk_opened_at {
            Some(t) if t.elapsed() >= self.flush_interval => self.flush(),
            _ => Ok(()),
        }
    }

    /// Closes the open chunk and hands the bytes to the OS.
    fn flush(&mut self) -> Result<(), WriteFailure> {
        self.writer.flush()?;
        self.chunk_opened_at = None;
        Ok(())
    }

    fn finish(
        self,
        stats_channel: Option<u16>,
        outcome: Option<(bool, Option<String>)>,
    ) -> Result<RecorderStats, SessionError> {
        let stats = RecorderStats {
            messages_written: self.messages_written,
            images_dropped: self.shared.images_dropped.load(Ordering::Relaxed),
        };
        let WriterThread { mut writer, shared, last_log_time, mut live, .. } = self;
        let written = write_end(&mut writer, last_log_time, stats, stats_channel, outcome);
        if let (Some(live), Some(id), Ok(())) = (&mut live, stats_channel, &written) {
            forward_stats(live, id, last_log_time, stats);
        }
        if let Some(live) = &live {
            live.finished();
        }
        let closed = match written {
            Ok(()) => close(writer),
            Err(failure) => {
                abandon(writer);
                Err(failure)
            }
        };
        closed.map(|()| stats).map_err(|failure| {
            shared.fail(failure);
            shared.closed()
        })
    }

    /// After a failure: leave the file as a crash would (no more writes),
    /// discard everything until `Finish` so producers never block on a dead
    /// writer, then report the failure.
    fn drain(self) -> Result<RecorderStats, SessionError> {
        let WriterThread { writer, rx, shared, live, .. } = self;
        abandon(writer);
        if let Some(live) = &live {
            live.finished();
        }
        for cmd in rx.iter() {
            match cmd {
                Command::Message { lossy: true, payload, .. } => {
                    shared.lossy_bytes_queued.fetch_sub(payload.len(), Ordering::AcqRel);
                }
                Command::Finish { .. } => break,
                _ => {}
            }
        }
        Err(shared.closed())
    }
}

/// The live view of a registration.
fn live_channel(r: ChannelRegistration) -> LiveChannel {
    LiveChannel {
        topic: r.topic,
        schema_name: r.schema_name,
        schema_encoding: r.schema_encoding,
        schema_data: r.schema_data,
        message_encoding: r.message_encoding,
        metadata: r.metadata,
    }
}

/// Hands the `/recorder/stats` channel and message, written at the end, to the live viewer.
fn forward_stats(live: &mut LiveSession, id: u16, t: TimeNs, stats: RecorderStats) {
    let Ok(payload) = serde_json::to_vec(&stats) else { return };
    live.channel(
        id,
        LiveChannel {
            topic: RecorderStats::TOPIC.into(),
            schema_name: RecorderStats::SCHEMA_NAME.into(),
            schema_encoding: SCHEMA_ENCODING_JSONSCHEMA.into(),
            schema_data: RecorderStats::json_schema().to_string().into_bytes(),
            message_encoding: MESSAGE_ENCODING_JSON.into(),
            metadata: BTreeMap::new(),
        },
    );
    live.message(id, t, t, 0, payload);
}

/// Drops a writer without writing anything more: no summary, and bytes still
/// buffered are discarded. The file stays as a crash would have left it.
fn abandon(writer: McapWriter) {
    let (file, _unwritten) = writer.into_inner().into_parts();
    drop(file);
}

/// Writes the stats message, the outcome record and the summary.
fn write_end(
    writer: &mut McapWriter,
    last_log_time: TimeNs,
    stats: RecorderStats,
    stats_channel: Option<u16>,
    outcome: Option<(bool, Option<String>)>,
) -> Result<(), WriteFailure> {
    if let Some(id) = stats_channel {
        let schema = RecorderStats::json_schema().to_string();
        let schema_id =
            writer.add_schema(RecorderStats::SCHEMA_NAME, SCHEMA_ENCODING_JSONSCHEMA, schema.as_bytes())?;
        let no_metadata = BTreeMap::new();
        let topic = RecorderStats::TOPIC;
        writer.add_channel_with_id(id, schema_id, topic, MESSAGE_ENCODING_JSON, &no_metadata)?;
        let payload = serde_json::to_vec(&stats).map_err(|e| WriteFailure::Encode(Arc::new(e)))?;
        let t = last_log_time.0;
        let header = MessageHeader { channel_id: id, sequence: 0, log_time: t, publish_time: t };
        writer.write_to_known_channel(&header, &payload)?;
    }
    if let Some((completed, abort_reason)) = outcome {
        let images_dropped = stats.images_dropped;
        let outcome = SessionOutcome { completed, abort_reason, images_dropped };
        let record = Metadata { name: OUTCOME_METADATA.into(), metadata: outcome.to_map() };
        writer.write_metadata(&record)?;
    }
    writer.finish()?;
    Ok(())
}

/// Hands the finished file's last bytes to the sink and syncs it.
fn close(writer: McapWriter) -> Result<(), WriteFailure> {
    let mut sink = writer.into_inner().into_inner().map_err(|e| e.into_error())?;
    sink.sync()?;
    Ok(())
}
