//! [`LiveServer`]: the Foxglove WebSocket server of a live run.

use std::net::SocketAddr;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use foxglove::websocket::{ChannelView, Client, ServerListener};
use foxglove::{Context, WebSocketServer, WebSocketServerHandle};
use slidetrack_session::{LiveReceiver, LiveTap, LiveTapStats};

use super::address::resolve_addr;
use super::background::{BackgroundRuntime, run_behind_the_recording};
use super::error::LiveError;
use super::front_door;
use super::publisher::{NewSubscriber, Publisher, PublisherStats};

/// Longest wait for the server's connections to close at shutdown: a viewer
/// that does not read holds its connection open (its socket is full).
const STOP_WAIT: Duration = Duration::from_secs(1);

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

/// How long connected viewers get to subscribe to the last channels and
/// receive the last messages at shutdown.
const STOP_GRACE: Duration = Duration::from_millis(300);

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
///   nothing is queued at all. The publisher and the server's threads run
///   at nice 19, so on a busy core the recording gets the time and the
///   viewer the messages that fit (see `background.rs`).
pub struct LiveServer {
    server: Arc<WebSocketServerHandle>,
    addr: SocketAddr,
    tap: LiveTap,
    stop: Arc<AtomicBool>,
    /// The publisher thread; it hands the publisher and its queue back at shutdown.
    publisher: Option<JoinHandle<(Publisher, LiveReceiver)>>,
    /// The server's runtime, driven at nice 19 until shutdown.
    runtime: BackgroundRuntime,
    /// The front door's accepting task (see `front_door.rs`).
    front_door: tokio::task::JoinHandle<()>,
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
        let mut runtime = BackgroundRuntime::new()?;
        let (new_subscribers, subscribed) = crossbeam_channel::unbounded();
        let listener =
            Arc::new(Subscriptions { active: AtomicUsize::new(0), tap: tap.clone(), new_subscribers });
        // Viewers connect to the front door, which relays them to the SDK's
        // server on loopback (and lets `foxglove.websocket.v1` in).
        let door = runtime
            .block_on(tokio::net::TcpListener::bind(requested))
            .map_err(|source| LiveError::Bind { addr: requested, source })?;
        let addr = door.local_addr().map_err(|source| LiveError::Bind { addr: requested, source })?;
        let starting = WebSocketServer::new()
            .name(format!("slidetrack {}", env!("CARGO_PKG_VERSION")))
            .context(&context)
            .listener(listener)
            .message_backlog_size(options.viewer_backlog.max(1))
            .tokio_runtime(runtime.handle())
            .bind(front_door::BACKEND_HOST, 0)
            .start();
        let server = runtime.block_on(starting).map_err(|e| LiveError::starting(requested, e))?;
        let front_door =
            runtime.handle().spawn(front_door::serve(door, front_door::backend_addr(server.port())));
        runtime.drive_in_background()?;
        let server = Arc::new(server);
        let stop = Arc::new(AtomicBool::new(false));
        let mut publisher = Publisher::new(context, Arc::clone(&server), options.image_max_hz, subscribed);
        let thread = {
            let stop = Arc::clone(&stop);
            std::thread::Builder::new()
                .name("live-publisher".into())
                .spawn(move || {
                    run_behind_the_recording();
                    publisher.run(&rx, &stop);
                    (publisher, rx)
                })
                .map_err(LiveError::Thread)?
        };
        Ok(LiveServer { server, addr, tap, stop, publisher: Some(thread), runtime, front_door })
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

    /// Waits until at least one viewer is connected, at most `timeout`;
    /// whether one is.
    pub fn wait_for_viewer(&self, timeout: Duration) -> bool {
        let deadline = std::time::Instant::now() + timeout;
        while self.viewers() == 0 {
            if std::time::Instant::now() >= deadline {
                return false;
            }
            std::thread::sleep(Duration::from_millis(10));
        }
        true
    }

    /// Publishes what is still queued, stops the server and returns the counts.
    ///
    /// The caller's thread takes over from the background threads (see
    /// `background.rs`): it publishes what the recorders queued, gives
    /// viewers [`STOP_GRACE`] to subscribe to the last channels (the
    /// recorder's statistics) and receive the last messages, and stops the
    /// server, all at the caller's priority.
    pub fn shutdown(self) -> LiveStats {
        let LiveServer { server, tap, stop, publisher, mut runtime, front_door, .. } = self;
        stop.store(true, Ordering::Release);
        let publisher = publisher.and_then(|t| t.join().ok());
        runtime.hand_over();
        let mut stats = PublisherStats::default();
        if let Some((mut publisher, rx)) = publisher {
            let grace = if server.client_count() > 0 { STOP_GRACE } else { Duration::ZERO };
            runtime.block_on(catch_up(&mut publisher, &rx, grace));
            stats = publisher.stats();
        }
        front_door.abort();
        // The publisher has let go of its handle.
        if let Ok(server) = Arc::try_unwrap(server) {
            let stopping = server.stop();
            // (The timer is made inside the runtime.)
            if runtime.block_on(async { tokio::time::timeout(STOP_WAIT, stopping.wait()).await }).is_err() {
                tracing::debug!("live: a viewer did not close its connection; leaving it");
            }
        }
        LiveStats { tap: tap.stats(), published: stats.published, images_throttled: stats.images_throttled }
    }
}

/// Longest the catch-up at shutdown goes on while recorders still queue
/// messages (a recorder that outlives the server).
const CATCH_UP_LIMIT: Duration = Duration::from_secs(10);

/// How often the catch-up looks at the queue while the runtime sends.
const CATCH_UP_POLL: Duration = Duration::from_millis(5);

/// Publishes what is queued until the queue stays empty and `grace` has
/// passed, the runtime sending to viewers and taking their subscriptions
/// in between; then gives the last messages a moment to go out.
async fn catch_up(publisher: &mut Publisher, rx: &LiveReceiver, grace: Duration) {
    let start = Instant::now();
    loop {
        let busy = publisher.catch_up(rx);
        let elapsed = start.elapsed();
        if (!busy && elapsed >= grace) || elapsed >= CATCH_UP_LIMIT {
            break;
        }
        tokio::time::sleep(CATCH_UP_POLL).await;
    }
    if !grace.is_zero() {
        tokio::time::sleep(STOP_GRACE / 4).await;
    }
}
