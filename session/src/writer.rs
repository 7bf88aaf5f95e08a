//! The producers' side of recording: the [`Logger`] handle, the channel
//! registry and the state shared with the writer thread.

use std::collections::BTreeMap;
use std::marker::PhantomData;
use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::time::Duration;

use crossbeam_channel::{Sender, TrySendError};
use serde::Serialize;
use slidetrack_core::TimeNs;

use super::channel::{ChannelMessage, MESSAGE_ENCODING_JSON, SCHEMA_ENCODING_JSONSCHEMA};
use super::error::SessionError;
use super::live::LiveTap;
use super::shared::{ChannelRegistration, Command, Shared, lock};

/// Tuning of a [`Recorder`](super::Recorder). The defaults suit a 1 kHz tactile stream plus a
/// 30 fps camera.
#[derive(Clone, Debug, PartialEq)]
pub struct RecorderOptions {
    /// A chunk is closed once its uncompressed size exceeds this (bytes).
    pub chunk_size_bytes: u64,
    /// A chunk is closed (and handed to the OS) at the latest this long after
    /// its first record, so a killed process loses at most this much.
    pub flush_interval: Duration,
    /// Records the queue holds before [`Logger::log`] blocks.
    pub queue_capacity: usize,
    /// Payload bytes of lossy records (images) the queue may hold; beyond
    /// this [`Logger::log_lossy`] drops.
    pub lossy_queue_bytes: usize,
    /// Replace an existing file at the path. Off by default: recording over
    /// an earlier session fails instead.
    pub overwrite: bool,
    /// zstd level. 1 (the default) is the fastest standard level, and on
    /// tactile JSON it also compresses better than zstd's default (0, meaning 3).
    pub compression_level: u32,
    /// Hand every channel and message, once written, to a live viewer
    /// (see [`LiveTap`]); never waits for it. None by default.
    pub live: Option<LiveTap>,
}

impl Default for RecorderOptions {
    fn default() -> Self {
        RecorderOptions {
            chunk_size_bytes: 4 << 20,
            flush_interval: Duration::from_secs(1),
            queue_capacity: 16_384,
            lossy_queue_bytes: 64 << 20,
            overwrite: false,
            compression_level: 1,
            live: None,
        }
    }
}

/// The message type of a channel registered with raw payloads
/// ([`Logger::register_channel`]): any bytes, in the channel's own encoding.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Untyped {}

/// A registered channel whose messages are `T` (a [`ChannelMessage`], or
/// [`Untyped`] bytes). Cheap to clone; valid only with the recorder that made
/// it. Logging a message on a handle of another type does not compile:
///
/// ```
/// # use slidetrack_core::TimeNs;
/// # use slidetrack_session::{HandCommand, Recorder, TactileRaw};
/// # fn record(rec: &Recorder) -> Result<(), slidetrack_session::SessionError> {
/// let raw = rec.register::<TactileRaw>(Default::default())?;
/// rec.log_json(&raw, TimeNs(0), TimeNs(0), 0, &TactileRaw::default())?;
/// # Ok(()) }
/// ```
///
/// ```compile_fail
/// # use slidetrack_core::TimeNs;
/// # use slidetrack_session::{HandCommand, Recorder, TactileRaw};
/// # fn record(rec: &Recorder) -> Result<(), slidetrack_session::SessionError> {
/// let hand = rec.register::<HandCommand>(Default::default())?;
/// rec.log_json(&hand, TimeNs(0), TimeNs(0), 0, &TactileRaw::default())?; // a scan on /hand/command
/// # Ok(()) }
/// ```
pub struct ChannelHandle<T = Untyped> {
    pub(crate) id: u16,
    topic: Arc<str>,
    message: PhantomData<fn(&T)>,
}

impl<T> ChannelHandle<T> {
    fn new(id: u16, topic: Arc<str>) -> ChannelHandle<T> {
        ChannelHandle { id, topic, message: PhantomData }
    }

    /// The same channel, for raw payloads.
    fn untyped(&self) -> ChannelHandle<Untyped> {
        ChannelHandle::new(self.id, Arc::clone(&self.topic))
    }

    /// The channel's topic.
    pub fn topic(&self) -> &str {
        &self.topic
    }
}

impl<T> Clone for ChannelHandle<T> {
    fn clone(&self) -> Self {
        ChannelHandle::new(self.id, Arc::clone(&self.topic))
    }
}

impl<T> std::fmt::Debug for ChannelHandle<T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ChannelHandle").field("id", &self.id).field("topic", &self.topic).finish()
    }
}

impl<T> PartialEq for ChannelHandle<T> {
    fn eq(&self, other: &Self) -> bool {
        self.id == other.id && self.topic == other.topic
    }
}

impl<T> Eq for ChannelHandle<T> {}

/// A cloneable handle for producer threads: everything a [`Recorder`](super::Recorder) offers
/// except finishing. Calls fail with [`SessionError::Closed`] once the
/// recorder has finished.
#[derive(Clone)]
pub struct Logger {
    pub(crate) tx: Sender<Command>,
    pub(crate) shared: Arc<Shared>,
}

impl Logger {
    /// Registers a channel and returns its handle. Registering the same topic
    /// again with identical arguments returns the same handle; with different
    /// arguments it fails. An empty `schema_name` and `schema_encoding` mean no schema.
    pub fn register_channel(
        &self,
        topic: &str,
        schema_name: &str,
        schema_encoding: &str,
        schema: &[u8],
        message_encoding: &str,
        channel_metadata: BTreeMap<String, String>,
    ) -> Result<ChannelHandle<Untyped>, SessionError> {
        self.shared.check()?;
        let registration = ChannelRegistration {
            topic: topic.to_string(),
            schema_name: schema_name.to_string(),
            schema_encoding: schema_encoding.to_string(),
            schema_data: schema.to_vec(),
            message_encoding: message_encoding.to_string(),
            metadata: channel_metadata,
        };
        let mut reg = lock(&self.shared.registry);
        if let Some((id, existing)) = reg.by_topic.get(topic) {
            if *existing == registration {
                return Ok(ChannelHandle::new(*id, topic.into()));
            }
            return Err(SessionError::Channel {
                path: self.shared.path.clone(),
                topic: topic.to_string(),
                detail: "already registered with a different schema, encoding or metadata".into(),
            });
        }
        let id = self.shared.alloc_id(&mut reg, topic)?;
        let handle = ChannelHandle::new(id, topic.into());
        reg.by_topic.insert(topic.to_string(), (id, registration.clone()));
        // Send while holding the registry lock, so that no producer can log on
        // this channel before the writer thread has seen it.
        self.tx
            .send(Command::Channel { id, registration: Box::new(registration) })
            .map_err(|_| self.shared.closed())?;
        Ok(handle)
    }

    /// Registers `T`'s channel (JSON messages, JSON Schema).
    pub fn register<T: ChannelMessage>(
        &self,
        channel_metadata: BTreeMap<String, String>,
    ) -> Result<ChannelHandle<T>, SessionError> {
        let schema = T::json_schema().to_string();
        let untyped = self.register_channel(
            T::TOPIC,
            T::SCHEMA_NAME,
            SCHEMA_ENCODING_JSONSCHEMA,
            schema.as_bytes(),
            MESSAGE_ENCODING_JSON,
            channel_metadata,
        )?;
        Ok(ChannelHandle::new(untyped.id, untyped.topic))
    }

    /// Queues a message, blocking while the queue is full: nothing logged
    /// here is ever dropped. Fails with the writer's error once a write failed.
    pub fn log(
        &self,
        channel: &ChannelHandle<Untyped>,
        log_time: TimeNs,
        publish_time: TimeNs,
        sequence: u32,
        payload: Vec<u8>,
    ) -> Result<(), SessionError> {
        self.shared.check()?;
        let cmd =
            Command::Message { channel: channel.id, log_time, publish_time, sequence, payload, lossy: false };
        self.tx.send(cmd).map_err(|_| self.shared.closed())
    }

    /// Queues a message unless the queue is full or holds too many lossy
    /// bytes already; never blocks. Returns whether the message was queued,
    /// and counts a drop when it was not.
    pub fn log_lossy(
        &self,
        channel: &ChannelHandle<Untyped>,
        log_time: TimeNs,
        publish_time: TimeNs,
        sequence: u32,
        payload: Vec<u8>,
    ) -> Result<bool, SessionError> {
        self.shared.check()?;
        let len = payload.len();
        let queued = self.shared.lossy_bytes_queued.fetch_add(len, Ordering::AcqRel);
        let accepted = queued.saturating_add(len) <= self.shared.lossy_limit
            && match self.tx.try_send(Command::Message {
                channel: channel.id,
                log_time,
                publish_time,
                sequence,
                payload,
                lossy: true,
            }) {
                Ok(()) => true,
                Err(TrySendError::Full(_)) => false,
                Err(TrySendError::Disconnected(_)) => {
                    self.shared.lossy_bytes_queued.fetch_sub(len, Ordering::AcqRel);
                    return Err(self.shared.closed());
                }
            };
        if !accepted {
            self.shared.lossy_bytes_queued.fetch_sub(len, Ordering::AcqRel);
            self.shared.images_dropped.fetch_add(1, Ordering::Relaxed);
        }
        Ok(accepted)
    }

    /// Queues a message whose payload is computed elsewhere (an image
    /// encoded on another thread), blocking while the queue is full like
    /// [`Logger::log`]: it takes its place among the messages now, and the
    /// writer waits for its payload when it gets there, so the file is the
    /// same as if the payload had been logged here. Fill the returned
    /// [`PendingPayload`]; dropped unfilled, the message is left out.
    pub fn log_pending(
        &self,
        channel: &ChannelHandle<Untyped>,
        log_time: TimeNs,
        publish_time: TimeNs,
        sequence: u32,
    ) -> Result<PendingPayload, SessionError> {
        self.shared.check()?;
        let (tx, payload) = crossbeam_channel::bounded(1);
        let cmd = Command::Pending { channel: channel.id, log_time, publish_time, sequence, payload };
        self.tx.send(cmd).map_err(|_| self.shared.closed())?;
        Ok(PendingPayload { tx })
    }

    /// [`Logger::log_pending`] on a typed channel: fill it with
    /// [`PendingPayload::fill_json`].
    pub fn log_json_pending<T: Serialize>(
        &self,
        channel: &ChannelHandle<T>,
        log_time: TimeNs,
        publish_time: TimeNs,
        sequence: u32,
    ) -> Result<PendingPayload, SessionError> {
        self.log_pending(&channel.untyped(), log_time, publish_time, sequence)
    }

    fn encode<T: Serialize>(&self, channel: &ChannelHandle<T>, message: &T) -> Result<Vec<u8>, SessionError> {
        serde_json::to_vec(message).map_err(|source| SessionError::Encode {
            path: self.shared.path.clone(),
            topic: channel.topic().to_string(),
            source,
        })
    }

    /// [`Logger::log`] of `message` serialized as JSON.
    pub fn log_json<T: Serialize>(
        &self,
        channel: &ChannelHandle<T>,
        log_time: TimeNs,
        publish_time: TimeNs,
        sequence: u32,
        message: &T,
    ) -> Result<(), SessionError> {
        let payload = self.encode(channel, message)?;
        self.log(&channel.untyped(), log_time, publish_time, sequence, payload)
    }

    /// [`Logger::log_lossy`] of `message` serialized as JSON.
    pub fn log_json_lossy<T: Serialize>(
        &self,
        channel: &ChannelHandle<T>,
        log_time: TimeNs,
        publish_time: TimeNs,
        sequence: u32,
        message: &T,
    ) -> Result<bool, SessionError> {
        let payload = self.encode(channel, message)?;
        self.log_lossy(&channel.untyped(), log_time, publish_time, sequence, payload)
    }

    /// Queues an attachment (a calibration file, a config), stamped with the
    /// latest log time written so far. Blocks while the queue is full.
    pub fn attach(&self, name: &str, media_type: &str, data: Vec<u8>) -> Result<(), SessionError> {
        self.shared.check()?;
        let cmd = Command::Attachment { name: name.into(), media_type: media_type.into(), data };
        self.tx.send(cmd).map_err(|_| self.shared.closed())
    }

    /// Queues a metadata record. Blocks while the queue is full.
    pub fn metadata(&self, name: &str, map: BTreeMap<String, String>) -> Result<(), SessionError> {
        self.shared.check()?;
        self.tx.send(Command::Metadata { name: name.into(), map }).map_err(|_| self.shared.closed())
    }

    /// Lossy messages dropped so far.
    pub fn images_dropped(&self) -> u64 {
        self.shared.images_dropped.load(Ordering::Relaxed)
    }

    /// The session file.
    pub fn path(&self) -> &Path {
        &self.shared.path
    }
}

/// The payload of a message queued by [`Logger::log_pending`]; `Send`, so
/// another thread can compute and fill it.
#[derive(Debug)]
pub struct PendingPayload {
    tx: Sender<Vec<u8>>,
}

impl PendingPayload {
    /// Hands the payload to the writer.
    pub fn fill(self, payload: Vec<u8>) {
        // The writer gone (the recorder failed or finished): nothing to write to.
        let _ = self.tx.send(payload);
    }

    /// Hands `message` serialized as JSON (as [`Logger::log_json`] does);
    /// a message that does not serialize is left out.
    pub fn fill_json<T: Serialize>(self, message: &T) {
        if let Ok(payload) = serde_json::to_vec(message) {
            self.fill(payload);
        }
    }
}
