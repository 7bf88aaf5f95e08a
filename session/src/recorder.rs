//! The [`Recorder`]: opens the session file and starts its writer thread.

use std::collections::BTreeMap;
use std::fs::OpenOptions;
use std::io::BufWriter;
use std::path::Path;
use std::sync::Arc;
use std::thread::JoinHandle;

use serde::Serialize;
use slidetrack_core::TimeNs;

use super::channel::ChannelMessage;
use super::error::{SessionError, error_chain};
use super::live::LiveSession;
use super::messages::RecorderStats;
use super::metadata::SESSION_METADATA;
use super::shared::{Command, Shared};
use super::writer::{ChannelHandle, Logger, RecorderOptions, Untyped};
use super::writer_thread::{SessionSink, WriterThread};

/// Records one session to one MCAP file.
///
/// # Contract
/// - `create` opens the file before returning, so a missing or unwritable
///   directory, or an existing file (unless [`RecorderOptions::overwrite`]),
///   fails there, naming the path.
/// - Records are written in the order they were queued, by a thread named
///   `session-writer`, in zstd chunks. A chunk is closed when it exceeds
///   [`RecorderOptions::chunk_size_bytes`] and at the latest
///   [`RecorderOptions::flush_interval`] after its first record, so a killed
///   process leaves a file readable up to its last complete chunk.
/// - `log` blocks while the queue is full; `log_lossy` never blocks and drops.
/// - The first write failure (disk full) stops writing and leaves the file as
///   a crash would; the error is returned by every later call, including
///   `finish`. Nothing here panics on I/O errors.
/// - Dropping the recorder without `finish` finishes the file anyway, with an
///   outcome record saying so.
pub struct Recorder {
    logger: Logger,
    thread: Option<JoinHandle<Result<RecorderStats, SessionError>>>,
}

impl Recorder {
    /// Creates the session file at `path` with default options and writes the
    /// `slidetrack` metadata record `metadata` (see [`super::SessionMetadata`]).
    pub fn create(
        path: impl AsRef<Path>,
        metadata: BTreeMap<String, String>,
    ) -> Result<Recorder, SessionError> {
        Recorder::create_with_options(path, metadata, RecorderOptions::default())
    }

    /// [`Recorder::create`] with explicit options.
    pub fn create_with_options(
        path: impl AsRef<Path>,
        metadata: BTreeMap<String, String>,
        options: RecorderOptions,
    ) -> Result<Recorder, SessionError> {
        let path = path.as_ref().to_path_buf();
        let create_error = |source| SessionError::Create { path: path.clone(), source };
        let mut open = OpenOptions::new();
        open.write(true);
        if options.overwrite {
            open.create(true).truncate(true);
        } else {
            open.create_new(true);
        }
        let file = open.open(&path).map_err(create_error)?;
        Recorder::with_sink(path, file, metadata, options)
    }

    /// Records to `sink` instead of a file of its own; `path` names the
    /// session in messages and errors. `options.overwrite` does not apply.
    pub fn with_sink(
        path: impl AsRef<Path>,
        sink: impl SessionSink,
        metadata: BTreeMap<String, String>,
        options: RecorderOptions,
    ) -> Result<Recorder, SessionError> {
        let path = path.as_ref().to_path_buf();
        let create_error = |source| SessionError::Create { path: path.clone(), source };
        let out = BufWriter::with_capacity(256 << 10, Box::new(sink) as Box<dyn SessionSink>);
        let write_options = mcap::WriteOptions::new()
            .compression(Some(mcap::Compression::Zstd))
            .compression_level(options.compression_level)
            .compression_threads(0)
            .chunk_size(Some(options.chunk_size_bytes))
            .profile("")
            .library(format!("slidetrack {}", env!("CARGO_PKG_VERSION")));
        let writer = mcap::Writer::with_options(out, write_options).map_err(|e| {
            let io = match e {
                mcap::McapError::Io(io) => io,
                other => std::io::Error::other(other.to_string()),
            };
            create_error(io)
        })?;
        let (tx, rx) = crossbeam_channel::bounded(options.queue_capacity.max(1));
        let shared = Arc::new(Shared::new(path.clone(), options.lossy_queue_bytes));
        let live = options.live.map(|tap| LiveSession::start(tap, path.clone()));
        let worker = WriterThread::new(writer, rx, Arc::clone(&shared), options.flush_interval, live);
        let thread = std::thread::Builder::new()
            .name("session-writer".into())
            .spawn(move || worker.run())
            .map_err(create_error)?;
        let recorder = Recorder { logger: Logger { tx, shared }, thread: Some(thread) };
        recorder.logger.metadata(SESSION_METADATA, metadata)?;
        Ok(recorder)
    }

    /// A cloneable handle for producer threads.
    pub fn logger(&self) -> Logger {
        self.logger.clone()
    }

    /// The session file.
    pub fn path(&self) -> &Path {
        self.logger.path()
    }

    /// See [`Logger::register_channel`].
    pub fn register_channel(
        &self,
        topic: &str,
        schema_name: &str,
        schema_encoding: &str,
        schema: &[u8],
        message_encoding: &str,
        channel_metadata: BTreeMap<String, String>,
    ) -> Result<ChannelHandle<Untyped>, SessionError> {
        let l = &self.logger;
        l.register_channel(topic, schema_name, schema_encoding, schema, message_encoding, channel_metadata)
    }

    /// See [`Logger::register`].
    pub fn register<T: ChannelMessage>(
        &self,
        meta: BTreeMap<String, String>,
    ) -> Result<ChannelHandle<T>, SessionError> {
        self.logger.register::<T>(meta)
    }

    /// See [`Logger::log`].
    pub fn log(
        &self,
        ch: &ChannelHandle<Untyped>,
        log_time: TimeNs,
        publish_time: TimeNs,
        sequence: u32,
        payload: Vec<u8>,
    ) -> Result<(), SessionError> {
        self.logger.log(ch, log_time, publish_time, sequence, payload)
    }

    /// See [`Logger::log_lossy`].
    pub fn log_lossy(
        &self,
        ch: &ChannelHandle<Untyped>,
        log_time: TimeNs,
        publish_time: TimeNs,
        sequence: u32,
        payload: Vec<u8>,
    ) -> Result<bool, SessionError> {
        self.logger.log_lossy(ch, log_time, publish_time, sequence, payload)
    }

    /// See [`Logger::log_json`].
    pub fn log_json<T: Serialize>(
        &self,
        ch: &ChannelHandle<T>,
        log_time: TimeNs,
        publish_time: TimeNs,
        sequence: u32,
        message: &T,
    ) -> Result<(), SessionError> {
        self.logger.log_json(ch, log_time, publish_time, sequence, message)
    }

    /// See [`Logger::log_json_lossy`].
    pub fn log_json_lossy<T: Serialize>(
        &self,
        ch: &ChannelHandle<T>,
        log_time: TimeNs,
        publish_time: TimeNs,
        sequence: u32,
        message: &T,
    ) -> Result<bool, SessionError> {
        self.logger.log_json_lossy(ch, log_time, publish_time, sequence, message)
    }

    /// See [`Logger::attach`].
    pub fn attach(&self, name: &str, media_type: &str, data: Vec<u8>) -> Result<(), SessionError> {
        self.logger.attach(name, media_type, data)
    }

    /// See [`Logger::metadata`].
    pub fn metadata(&self, name: &str, map: BTreeMap<String, String>) -> Result<(), SessionError> {
        self.logger.metadata(name, map)
    }

    /// Lossy messages dropped so far.
    pub fn images_dropped(&self) -> u64 {
        self.logger.images_dropped()
    }

    /// Writes the `/recorder/stats` message and the summary, closes the file
    /// and returns the statistics. Records queued through [`Logger`] clones
    /// before this call are written; later ones fail with `Closed`.
    pub fn finish(mut self) -> Result<RecorderStats, SessionError> {
        self.finish_inner(None)
    }

    /// [`Recorder::finish`], writing the `slidetrack.outcome` metadata record first.
    pub fn finish_with_outcome(
        mut self,
        completed: bool,
        abort_reason: Option<String>,
    ) -> Result<RecorderStats, SessionError> {
        self.finish_inner(Some((completed, abort_reason)))
    }

    fn finish_inner(
        &mut self,
        outcome: Option<(bool, Option<String>)>,
    ) -> Result<RecorderStats, SessionError> {
        let shared = &self.logger.shared;
        let Some(thread) = self.thread.take() else {
            return Err(shared.closed());
        };
        let stats_channel = shared.next_channel_id(RecorderStats::TOPIC);
        // If the thread is gone already, join reports why.
        let sent = match stats_channel {
            Ok(id) => self.logger.tx.send(Command::Finish { stats_channel: Some(id), outcome }),
            Err(_) => self.logger.tx.send(Command::Finish { stats_channel: None, outcome }),
        };
        let joined = thread.join();
        match joined {
            Ok(result) => result,
            Err(_) => Err(SessionError::Closed {
                path: shared.path.clone(),
                detail: if sent.is_ok() { "its writer thread panicked" } else { "its writer thread exited" }
                    .into(),
            }),
        }
    }
}

impl Drop for Recorder {
    fn drop(&mut self) {
        if self.thread.is_some() {
            let reason = "the recorder was dropped without finish (early return or panic)".to_string();
            if let Err(e) = self.finish_inner(Some((false, Some(reason)))) {
                tracing::warn!("{}", error_chain(&e));
            }
        }
    }
}
