//! [`Ros2Publisher`]: the recorder's channels as ROS 2 topics, published by
//! a thread of its own that never holds the recording up.
//!
//! The recorder hands what it writes to a [`LiveTap`], the same tap the
//! Foxglove live view uses: a bounded queue that drops (and counts)
//! messages when it is full, and never blocks the writer thread. The
//! publisher thread runs at the lowest normal priority (nice 19), and so do
//! the DDS participant's own threads, which it starts: on a busy machine the
//! recording gets the cores and the ROS 2 side drops messages instead.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc;
use std::thread::JoinHandle;
use std::time::Duration;

use slidetrack_session::{LiveReceiver, LiveTap, LiveTapStats, TapClosed};
use thread_priority::{ThreadPriority, set_current_thread_priority};

use super::error::Ros2Error;
use super::node::{Node, NodeStats};

/// Options of [`Ros2Publisher::start`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Ros2Options {
    /// The ROS 2 domain id (see [`domain_id`](crate::domain_id)).
    pub domain: u16,
    /// Most messages queued for the publisher; beyond, messages are dropped.
    pub queue_messages: usize,
    /// Most payload bytes queued for the publisher; beyond, messages are dropped.
    pub queue_bytes: usize,
}

impl Default for Ros2Options {
    fn default() -> Self {
        Ros2Options { domain: 0, queue_messages: 65_536, queue_bytes: 64 << 20 }
    }
}

/// What the publisher did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Ros2Stats {
    /// Messages published and not published.
    pub node: NodeStats,
    /// The tap's forwarded and dropped messages (dropped: the queue was full).
    pub tap: LiveTapStats,
}

/// A DDS participant publishing what recorders write (see the module documentation).
pub struct Ros2Publisher {
    domain: u16,
    tap: LiveTap,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<NodeStats>>,
}

/// How often the thread looks at the stop flag while the queue is empty.
const POLL: Duration = Duration::from_millis(50);

impl Ros2Publisher {
    /// Joins the domain and starts publishing; a participant that cannot be
    /// created (sockets, ports) fails here, before any recording.
    pub fn start(options: &Ros2Options) -> Result<Ros2Publisher, Ros2Error> {
        let (tap, rx) = LiveTap::new(options.queue_messages, options.queue_bytes);
        tap.set_wanted(true);
        let stop = Arc::new(AtomicBool::new(false));
        let (ready_tx, ready_rx) = mpsc::sync_channel(1);
        let domain = options.domain;
        let thread_stop = Arc::clone(&stop);
        let thread = std::thread::Builder::new()
            .name("ros2-publisher".into())
            .spawn(move || {
                // First: the participant's threads inherit the niceness.
                if let Err(e) = set_current_thread_priority(ThreadPriority::Min) {
                    tracing::debug!("ros2: cannot lower the priority of the publisher: {e:?}");
                }
                match Node::join(domain) {
                    Ok(node) => {
                        let _ = ready_tx.send(Ok(()));
                        run(node, &rx, &thread_stop)
                    }
                    Err(e) => {
                        let _ = ready_tx.send(Err(e));
                        NodeStats::default()
                    }
                }
            })
            .map_err(|e| Ros2Error::Thread(e.to_string()))?;
        match ready_rx.recv() {
            Ok(Ok(())) => Ok(Ros2Publisher { domain, tap, stop, thread: Some(thread) }),
            Ok(Err(e)) => Err(e),
            Err(_) => Err(Ros2Error::Thread("it stopped before joining the domain".into())),
        }
    }

    /// The domain it publishes on.
    pub fn domain(&self) -> u16 {
        self.domain
    }

    /// Where a recorder hands what it writes
    /// ([`RecorderOptions::live`](slidetrack_session::RecorderOptions::live)).
    pub fn tap(&self) -> LiveTap {
        self.tap.clone()
    }

    /// Publishes what is still queued, leaves the domain; what it did.
    pub fn finish(mut self) -> Ros2Stats {
        self.stop.store(true, Ordering::Release);
        let node = self.thread.take().and_then(|t| t.join().ok()).unwrap_or_default();
        Ros2Stats { node, tap: self.tap.stats() }
    }
}

impl Drop for Ros2Publisher {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Release);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// Publishes the tap's records until it is closed, or stopped and empty.
fn run(mut node: Node, rx: &LiveReceiver, stop: &AtomicBool) -> NodeStats {
    loop {
        match rx.recv_timeout(POLL) {
            Ok(Some(record)) => node.handle(record),
            Ok(None) if stop.load(Ordering::Acquire) => break,
            Ok(None) => {}
            Err(TapClosed) => break,
        }
    }
    node.stats()
}
