//! The recorder's live tap: every channel and message the writer thread has
//! written, handed on to a live viewer (the Foxglove server of
//! `slidetrack-live`) without ever waiting for it.
//!
//! The tap sits at the end of the writer thread: a message is forwarded once
//! it is in the file, its payload moved, not copied. Channel and session
//! records are always forwarded (there are a few dozen per session);
//! messages are forwarded only while the viewer side wants them
//! ([`LiveTap::set_wanted`]), except the latest of each channel, kept and
//! forwarded when a viewer comes; they are dropped, and counted, when the
//! queue holds [`LiveTap::new`]'s limit of messages or payload bytes. Nothing on this path
//! blocks, so the recording is the same with or without a viewer.

use std::collections::{BTreeMap, HashMap};
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::time::Duration;

use crossbeam_channel::{Receiver, RecvTimeoutError, Sender};
use slidetrack_core::TimeNs;

/// A channel as registered with the recorder: everything a viewer needs to
/// advertise it under the same topic and schema.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct LiveChannel {
    /// Topic (`/tactile/raw`).
    pub topic: String,
    /// Schema name (`slidetrack.TactileRaw`, `foxglove.CompressedImage`); empty without a schema.
    pub schema_name: String,
    /// Schema encoding (`jsonschema`); empty without a schema.
    pub schema_encoding: String,
    /// The schema itself.
    pub schema_data: Vec<u8>,
    /// Message encoding (`json`).
    pub message_encoding: String,
    /// Channel metadata (the taxel layout on `/tactile/raw`).
    pub metadata: BTreeMap<String, String>,
}

/// What the writer thread hands to the viewer side, in the order it wrote it.
/// `session` numbers the recorders of one tap (1, 2, ...): channel ids are
/// per session.
#[derive(Clone, Debug, PartialEq)]
pub enum LiveRecord {
    /// A recorder started writing `path`.
    SessionStarted {
        /// The recorder's number.
        session: u64,
        /// Its session file.
        path: PathBuf,
    },
    /// A channel was added to the file.
    Channel {
        /// The recorder's number.
        session: u64,
        /// The channel id in that session.
        id: u16,
        /// The channel.
        channel: Arc<LiveChannel>,
    },
    /// A message was written to the file.
    Message {
        /// The recorder's number.
        session: u64,
        /// The channel id in that session.
        channel: u16,
        /// Log time (ns, session clock).
        log_time: TimeNs,
        /// Publish time (ns, the device's clock where it has one).
        publish_time: TimeNs,
        /// The device's sequence number.
        sequence: u32,
        /// The payload, as written.
        payload: Vec<u8>,
    },
    /// The recorder finished its file (or stopped at a write failure).
    SessionFinished {
        /// The recorder's number.
        session: u64,
    },
}

/// Counters and limits shared by the tap's ends.
#[derive(Debug)]
struct TapState {
    max_messages: usize,
    max_bytes: usize,
    queued_messages: AtomicUsize,
    queued_bytes: AtomicUsize,
    wanted: AtomicBool,
    forwarded: AtomicU64,
    dropped: AtomicU64,
    sessions: AtomicU64,
}

/// The writer threads' end of a live tap; cheap to clone. Give it to
/// [`RecorderOptions::live`](super::RecorderOptions::live).
#[derive(Clone, Debug)]
pub struct LiveTap {
    tx: Sender<LiveRecord>,
    state: Arc<TapState>,
    /// Further taps that get everything too ([`LiveTap::and`]).
    also: Vec<LiveTap>,
}

impl PartialEq for LiveTap {
    fn eq(&self, other: &Self) -> bool {
        Arc::ptr_eq(&self.state, &other.state) && self.also == other.also
    }
}

/// The viewer's end of a live tap.
#[derive(Debug)]
pub struct LiveReceiver {
    rx: Receiver<LiveRecord>,
    state: Arc<TapState>,
}

/// Every [`LiveTap`] of a receiver is gone and its queue is empty.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TapClosed;

/// Counts of a live tap.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LiveTapStats {
    /// Messages handed to the viewer side.
    pub forwarded: u64,
    /// Messages dropped because the viewer side was behind (queue full).
    pub dropped: u64,
}

impl LiveTap {
    /// A tap whose queue holds at most `max_messages` messages and
    /// `max_bytes` payload bytes; beyond either, messages are dropped. It
    /// forwards no message until [`LiveTap::set_wanted`]`(true)`.
    pub fn new(max_messages: usize, max_bytes: usize) -> (LiveTap, LiveReceiver) {
        let (tx, rx) = crossbeam_channel::unbounded();
        let state = Arc::new(TapState {
            max_messages: max_messages.max(1),
            max_bytes,
            queued_messages: AtomicUsize::new(0),
            queued_bytes: AtomicUsize::new(0),
            wanted: AtomicBool::new(false),
            forwarded: AtomicU64::new(0),
            dropped: AtomicU64::new(0),
            sessions: AtomicU64::new(0),
        });
        (LiveTap { tx, state: Arc::clone(&state), also: Vec::new() }, LiveReceiver { rx, state })
    }

    /// A tap that hands everything to this one and to `other` too: one
    /// recorder, two outlets (`--live` and `--ros2`). Each keeps its own
    /// queue, limits, subscribers and counts (a payload both want is copied
    /// once); [`LiveTap::stats`] and [`LiveTap::set_wanted`] of the result
    /// are this one's.
    pub fn and(&self, other: &LiveTap) -> LiveTap {
        let mut tap = self.clone();
        tap.also.push(other.alone());
        tap.also.extend(other.also.iter().cloned());
        tap
    }

    /// This tap without the taps it hands on to.
    fn alone(&self) -> LiveTap {
        LiveTap { tx: self.tx.clone(), state: Arc::clone(&self.state), also: Vec::new() }
    }

    /// Whether anyone is subscribed: messages are forwarded only then.
    pub fn set_wanted(&self, wanted: bool) {
        self.state.wanted.store(wanted, Ordering::Release);
    }

    /// Forwarded and dropped messages so far.
    pub fn stats(&self) -> LiveTapStats {
        stats_of(&self.state)
    }

    /// Numbers a new session (1, 2, ...).
    pub(crate) fn next_session(&self) -> u64 {
        self.state.sessions.fetch_add(1, Ordering::AcqRel) + 1
    }

    /// Forwards a session or channel record; these are never dropped.
    pub(crate) fn control(&self, record: LiveRecord) {
        // A receiver that is gone wants nothing more.
        let _ = self.tx.send(record);
    }

    /// Whether anyone is subscribed.
    fn wanted(&self) -> bool {
        self.state.wanted.load(Ordering::Acquire)
    }

    /// Forwards a written message unless the queue is full.
    fn message(&self, record: LiveRecord) {
        let len = match &record {
            LiveRecord::Message { payload, .. } => payload.len(),
            _ => 0,
        };
        let s = &self.state;
        let messages = s.queued_messages.fetch_add(1, Ordering::AcqRel);
        let bytes = s.queued_bytes.fetch_add(len, Ordering::AcqRel);
        let room = messages < s.max_messages && bytes.saturating_add(len) <= s.max_bytes;
        if room && self.tx.send(record).is_ok() {
            s.forwarded.fetch_add(1, Ordering::Relaxed);
        } else {
            s.queued_messages.fetch_sub(1, Ordering::AcqRel);
            s.queued_bytes.fetch_sub(len, Ordering::AcqRel);
            s.dropped.fetch_add(1, Ordering::Relaxed);
        }
    }
}

impl LiveReceiver {
    /// The next record, waiting at most `timeout`; `Ok(None)` on timeout,
    /// [`TapClosed`] once every [`LiveTap`] is gone and the queue is empty.
    pub fn recv_timeout(&self, timeout: Duration) -> Result<Option<LiveRecord>, TapClosed> {
        match self.rx.recv_timeout(timeout) {
            Ok(record) => {
                if let LiveRecord::Message { payload, .. } = &record {
                    self.state.queued_messages.fetch_sub(1, Ordering::AcqRel);
                    self.state.queued_bytes.fetch_sub(payload.len(), Ordering::AcqRel);
                }
                Ok(Some(record))
            }
            Err(RecvTimeoutError::Timeout) => Ok(None),
            Err(RecvTimeoutError::Disconnected) => Err(TapClosed),
        }
    }

    /// Forwarded and dropped messages so far.
    pub fn stats(&self) -> LiveTapStats {
        stats_of(&self.state)
    }
}

fn stats_of(state: &TapState) -> LiveTapStats {
    LiveTapStats {
        forwarded: state.forwarded.load(Ordering::Relaxed),
        dropped: state.dropped.load(Ordering::Relaxed),
    }
}

/// A writer thread's use of its tap (and of the taps that tap hands on to,
/// [`LiveTap::and`]): per tap, its session number and the latest message
/// of each channel while nobody is subscribed (moved in, not copied),
/// forwarded first when someone subscribes: a viewer that comes late still
/// gets a calibration logged once at the start. A session played from its
/// file feeds a tap through one too (`play --ros2`).
pub struct LiveSession {
    taps: Vec<TapSession>,
}

impl LiveSession {
    /// Numbers the session on each tap and announces it.
    pub fn start(tap: LiveTap, path: PathBuf) -> LiveSession {
        let mut taps = vec![TapSession::start(tap.alone(), path.clone())];
        taps.extend(tap.also.into_iter().map(|t| TapSession::start(t, path.clone())));
        LiveSession { taps }
    }

    /// Announces channel `id` of the session.
    pub fn channel(&self, id: u16, channel: LiveChannel) {
        let channel = Arc::new(channel);
        for t in &self.taps {
            t.channel(id, Arc::clone(&channel));
        }
    }

    /// Hands on a message of channel `id` (log and publish times in ns of
    /// the session clock); never blocks (see [`LiveTap`]).
    pub fn message(
        &mut self,
        channel: u16,
        log_time: TimeNs,
        publish_time: TimeNs,
        sequence: u32,
        payload: Vec<u8>,
    ) {
        if let Some((last, first)) = self.taps.split_last_mut() {
            for t in first {
                t.message(channel, log_time, publish_time, sequence, payload.clone());
            }
            last.message(channel, log_time, publish_time, sequence, payload);
        }
    }

    /// Announces the end of the session.
    pub fn finished(&self) {
        for t in &self.taps {
            t.finished();
        }
    }
}

/// A [`LiveSession`] on one tap.
struct TapSession {
    tap: LiveTap,
    session: u64,
    latest: HashMap<u16, LiveRecord>,
    was_wanted: bool,
}

impl TapSession {
    fn start(tap: LiveTap, path: PathBuf) -> TapSession {
        let session = tap.next_session();
        tap.control(LiveRecord::SessionStarted { session, path });
        TapSession { tap, session, latest: HashMap::new(), was_wanted: false }
    }

    fn channel(&self, id: u16, channel: Arc<LiveChannel>) {
        self.tap.control(LiveRecord::Channel { session: self.session, id, channel });
    }

    fn message(
        &mut self,
        channel: u16,
        log_time: TimeNs,
        publish_time: TimeNs,
        sequence: u32,
        payload: Vec<u8>,
    ) {
        let session = self.session;
        let record = LiveRecord::Message { session, channel, log_time, publish_time, sequence, payload };
        if !self.tap.wanted() {
            self.latest.insert(channel, record);
            self.was_wanted = false;
            return;
        }
        if !self.was_wanted {
            self.was_wanted = true;
            let mut latest: Vec<_> = self.latest.drain().map(|(_, r)| r).collect();
            latest.sort_by_key(|r| match r {
                LiveRecord::Message { log_time, .. } => *log_time,
                _ => TimeNs::ZERO,
            });
            for r in latest {
                self.tap.message(r);
            }
        }
        self.tap.message(record);
    }

    fn finished(&self) {
        self.tap.control(LiveRecord::SessionFinished { session: self.session });
    }
}
