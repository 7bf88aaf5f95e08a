//! The state that the producers ([`Logger`](super::Logger)) share with the
//! recorder's writer thread: the channel registry, the first write failure,
//! the lossy-queue accounting, and the commands sent to the thread.

use std::collections::{BTreeMap, HashMap};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::{Mutex, MutexGuard, PoisonError};

use slidetrack_core::TimeNs;

use super::error::{SessionError, WriteFailure};

/// What producers send to the writer thread.
pub(crate) enum Command {
    Channel {
        id: u16,
        registration: Box<ChannelRegistration>,
    },
    Message {
        channel: u16,
        log_time: TimeNs,
        publish_time: TimeNs,
        sequence: u32,
        payload: Vec<u8>,
        /// Counted in `Shared::lossy_bytes_queued` until dequeued.
        lossy: bool,
    },
    /// A message whose payload another thread computes: the writer waits
    /// for it in its turn (see [`Logger::log_pending`](super::Logger::log_pending)).
    Pending {
        channel: u16,
        log_time: TimeNs,
        publish_time: TimeNs,
        sequence: u32,
        payload: crossbeam_channel::Receiver<Vec<u8>>,
    },
    Attachment {
        name: String,
        media_type: String,
        data: Vec<u8>,
    },
    Metadata {
        name: String,
        map: BTreeMap<String, String>,
    },
    /// Write the stats message (on this channel id) and the outcome, then the summary.
    Finish {
        stats_channel: Option<u16>,
        outcome: Option<(bool, Option<String>)>,
    },
}

/// Everything that defines a channel.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) struct ChannelRegistration {
    pub(crate) topic: String,
    pub(crate) schema_name: String,
    pub(crate) schema_encoding: String,
    pub(crate) schema_data: Vec<u8>,
    pub(crate) message_encoding: String,
    pub(crate) metadata: BTreeMap<String, String>,
}

/// State shared by the producers and the writer thread.
pub(crate) struct Shared {
    pub(crate) path: PathBuf,
    failed: AtomicBool,
    failure: Mutex<Option<WriteFailure>>,
    pub(crate) images_dropped: AtomicU64,
    pub(crate) lossy_bytes_queued: AtomicUsize,
    pub(crate) lossy_limit: usize,
    pub(crate) registry: Mutex<Registry>,
}

#[derive(Default)]
pub(crate) struct Registry {
    next_id: u32,
    pub(crate) by_topic: HashMap<String, (u16, ChannelRegistration)>,
}

pub(crate) fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

impl Shared {
    pub(crate) fn new(path: PathBuf, lossy_limit: usize) -> Shared {
        Shared {
            path,
            failed: AtomicBool::new(false),
            failure: Mutex::new(None),
            images_dropped: AtomicU64::new(0),
            lossy_bytes_queued: AtomicUsize::new(0),
            lossy_limit,
            registry: Mutex::new(Registry::default()),
        }
    }

    /// Records the first write failure; later calls report it.
    pub(crate) fn fail(&self, failure: WriteFailure) {
        let mut f = lock(&self.failure);
        if f.is_none() {
            *f = Some(failure);
        }
        self.failed.store(true, Ordering::Release);
    }

    /// The recorded failure, as an error.
    pub(crate) fn failure(&self) -> Option<SessionError> {
        if !self.failed.load(Ordering::Acquire) {
            return None;
        }
        let source = lock(&self.failure).clone()?;
        Some(SessionError::Write { path: self.path.clone(), kind: source.io_kind(), source })
    }

    /// The recorded failure, if any, as an error.
    pub(crate) fn check(&self) -> Result<(), SessionError> {
        self.failure().map_or(Ok(()), Err)
    }

    pub(crate) fn closed(&self) -> SessionError {
        self.failure().unwrap_or_else(|| SessionError::Closed {
            path: self.path.clone(),
            detail: "its writer thread has exited".into(),
        })
    }

    /// Reserves the next channel id (1, 2, ...).
    pub(crate) fn next_channel_id(&self, topic: &str) -> Result<u16, SessionError> {
        let mut reg = lock(&self.registry);
        self.alloc_id(&mut reg, topic)
    }

    /// Reserves the next channel id in `reg`.
    pub(crate) fn alloc_id(&self, reg: &mut Registry, topic: &str) -> Result<u16, SessionError> {
        reg.next_id += 1;
        u16::try_from(reg.next_id).map_err(|_| SessionError::Channel {
            path: self.path.clone(),
            topic: topic.to_string(),
            detail: "more than 65535 channels".into(),
        })
    }
}
