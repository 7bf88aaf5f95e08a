//! [`LiveServer`]: the Foxglove WebSocket server of a live run.

use std::net::SocketAddr;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::thread::JoinHandle;

use foxglove::websocket::{ChannelView, Client, ServerListener};
use foxglove::{Context, WebSocketServer, WebSocketServerHandle};
use slidetrack_session::{LiveTap, LiveTapStats};

use super::address::resolve_addr;
use super::error::LiveError;
use super::publisher::{NewSubscriber, Publisher, PublisherStats};

/// Longest wait for the server's connections to close at shutdown: a viewer
/// that does not read holds its connection open (its socket is full).
const STOP_WAIT: std::time::Duration = std::time::Duration::from_secs(1);

/// Stops `server`, waiting at most [`STOP_WAIT`] for its connections to close.
pub(crate) fn stop_server(server: WebSocketServerHandle) {
    let shutdown = server.stop();
    let (done, closed) = crossbeam_channel::bounded(1);
    let waiter = std::thread::Builder::new().name("live-stop".into()).spawn(move || {
        shutdown.wait_blocking();
        let _ = done.send(());
    });
    if waiter.is_ok() && closed.recv_timeout(STOP_WAIT).is_err() {
        tracing::debug!("live: a viewer did not close its connection; leaving it");
    }
}

/// How long connected viewers get to receive the last messages at shutdown.
const STOP_GRACE: std::time::Duration = std::time::Duration::from_millis(300);

/// How the live view publishes.
#[derive(Clone, Debug, PartialEq)]
pub struct LiveOptions {
    /// Most images per second and image channel sent to viewers (wall
    /// clock); 0 sends every image. Images only: every other message is sent.
    pub image_max_hz: f64,
    /// Messages the recorder may queue for the publisher before it drops.
    pub queue_messages: usize,
    /// Payload bytes the recorder may queue for the publisher before it drops.
    pub queue_bytes: usize,
    /// Most messages each viewer's own queue holds before the oldest are
    /// dropped (the Foxglove SDK's backlog).
    pub viewer_backlog: usize,
}

impl Default for LiveOptions {
    fn default() -> Self {
        LiveOptions {
            image_max_hz: 15.0,
            queue_messages: 65_536,
            queue_bytes: 64 << 20,
            viewer_backlog: 4096,
        }
    }
}

/// What the live view did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LiveStats {
    /// Messages the recorders handed over, and those they dropped because
    /// the publisher was behind.
    pub tap: LiveTapStats,
    /// Messages given to the Foxglove server (each viewer's queue may still
    /// drop its oldest when the viewer does not read).
    pub published: u64,
    /// Images left out by `image_max_hz`.
    pub images_throttled: u64,
}

/// A Foxglove WebSocket server publishing what recorders write through its
/// [`LiveServer::tap`].
///
/// # Contract
/// - [`LiveServer::start`] binds before returning: a port in use or an
///   address that is not this machine's fails there, with the address.
/// - Channels appear to viewers as the recorder adds them, with the same
///   topic, schema and encoding; each message is published with its log time
///   once the recorder has written it. A channel stays advertised across the
///   sessions of one server while its topic, schema and metadata do not
///   change; a new session after the first resets the viewers' state
///   (Foxglove's `clear_session`), as its clock starts again.
/// - A viewer that subscribes to a channel gets its latest message at once
///   (a calibration sent once, the last protocol event), then the new ones.
/// - Nothing here blocks a recorder: messages go through a bounded queue
///   (dropped when full), then to the SDK, whose per-viewer queues drop the
///   oldest messages of a viewer that does not read. No viewer subscribed:
///   nothing is queued at all.
pub struct LiveServer {
    server: Arc<WebSocketServerHandle>,
    addr: SocketAddr,
    tap: LiveTap,
    stop: Arc<AtomicBool>,
    publisher: Option<JoinHandle<PublisherStats>>,
}

/// Turns the tap on while at least one channel has a subscriber, and tells
/// the publisher who subscribed to what (it sends them the channel's latest message).
struct Subscriptions {
    active: AtomicUsize,
    tap: LiveTap,
    new_subscribers: crossbeam_channel::Sender<NewSubscriber>,
}

impl ServerListener for Subscriptions {
    fn on_subscribe(&self, client: Client, channel: ChannelView) {
        self.active.fetch_add(1, Ordering::AcqRel);
        self.tap.set_wanted(true);
        if let Some(sink) = client.sink_id() {
            let _ = self.new_subscribers.send(NewSubscriber { topic: channel.topic().to_string(), sink });
        }
    }

    fn on_unsubscribe(&self, _client: Client, _channel: ChannelView) {
        let left = self.active.fetch_sub(1, Ordering::AcqRel).saturating_sub(1);
        if left == 0 {
            self.tap.set_wanted(false);
        }
    }
}

impl LiveServer {
    /// Starts serving on `addr` (`HOST:PORT`, port 0 for a free one).
    pub fn start(addr: &str, options: &LiveOptions) -> Result<LiveServer, LiveError> {
        let requested = resolve_addr(addr)?;
        let (tap, rx) = LiveTap::new(options.queue_messages, options.queue_bytes);
        let context = Context::new();
        let (new_subscribers, subscribed) = crossbeam_channel::unbounded();
        let listener =
            Arc::new(Subscriptions { active: AtomicUsize::new(0), tap: tap.clone(), new_subscribers });
        let server = WebSocketServer::new()
            .name(format!("slidetrack {}", env!("CARGO_PKG_VERSION")))
            .context(&context)
            .listener(listener)
            .message_backlog_size(options.viewer_backlog.max(1))
            .bind(requested.ip().to_string(), requested.port())
            .start_blocking()
            .map_err(|e| LiveError::starting(requested, e))?;
        let addr = SocketAddr::new(requested.ip(), server.port());
        let server = Arc::new(server);
        let stop = Arc::new(AtomicBool::new(false));
        let publisher = Publisher::new(context, Arc::clone(&server), options.image_max_hz, subscribed);
        let thread = {
            let stop = Arc::clone(&stop);
            std::thread::Builder::new()
                .name("live-publisher".into())
                .spawn(move || publisher.run(&rx, &stop))
                .map_err(LiveError::Thread)?
        };
        Ok(LiveServer { server, addr, tap, stop, publisher: Some(thread) })
    }

    /// The address viewers connect to (the bound port when 0 was asked).
    pub fn local_addr(&self) -> SocketAddr {
        self.addr
    }

    /// The URL to open in Foxglove (`ws://127.0.0.1:8765`).
    pub fn url(&self) -> String {
        format!("ws://{}", self.addr)
    }

    /// The recorders' end: put it in [`slidetrack_session::RecorderOptions::live`].
    pub fn tap(&self) -> LiveTap {
        self.tap.clone()
    }

    /// Viewers connected now.
    pub fn viewers(&self) -> usize {
        self.server.client_count()
    }

    /// Publishes what is still queued, stops the server and returns the counts.
    pub fn shutdown(self) -> LiveStats {
        let LiveServer { server, tap, stop, publisher, .. } = self;
        // Viewers get a moment to subscribe to the last channels (the
        // recorder's statistics) and receive the last messages before the
        // publisher stops; the SDK drops what is still queued at stop.
        if server.client_count() > 0 {
            std::thread::sleep(STOP_GRACE);
        }
        stop.store(true, Ordering::Release);
        let published = publisher.and_then(|t| t.join().ok()).unwrap_or_default();
        if server.client_count() > 0 {
            std::thread::sleep(STOP_GRACE / 4);
        }
        // The publisher has let go of its handle.
        if let Ok(server) = Arc::try_unwrap(server) {
            stop_server(server);
        }
        LiveStats {
            tap: tap.stats(),
            published: published.published,
            images_throttled: published.images_throttled,
        }
    }
}
