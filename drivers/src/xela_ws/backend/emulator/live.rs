//! The emulator fed live: text messages arrive on a channel as they are
//! made (the simulated rig's scans) and go to the connected client at once;
//! the feed can also take the server down for a while or for good.

use std::io;
use std::net::{Shutdown, SocketAddr, TcpListener, TcpStream};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::time::{Duration, Instant};

use crossbeam_channel::{Receiver, RecvTimeoutError};
use tungstenite::protocol::Message;
use tungstenite::{Error as WsError, WebSocket};

/// How often a server thread (this one's and the recorded emulator's)
/// looks at its stop flag while it waits (ms).
pub(super) const POLL: Duration = Duration::from_millis(2);

/// What a live feed sends to the emulator.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum LiveMessage {
    /// A text message, sent at once to the connected client; lost when no
    /// client is connected (the server does not keep messages for clients).
    Text(String),
    /// Drop the connection (TCP shut down without a WebSocket close, as a
    /// crashed server) and refuse connections for this long; `None`: for good.
    Disconnect(Option<Duration>),
}

/// How a live connection ended.
enum LiveEnd {
    Stopped,
    ClientLeft,
    Down(Option<Duration>),
}

pub(super) struct LiveServer {
    pub(super) listener: Option<TcpListener>,
    pub(super) addr: SocketAddr,
    pub(super) welcome: Option<String>,
    pub(super) feed: Receiver<LiveMessage>,
    pub(super) stop: Arc<AtomicBool>,
    pub(super) sent: Arc<AtomicUsize>,
    pub(super) connections: Arc<AtomicUsize>,
}

impl LiveServer {
    pub(super) fn run(mut self) {
        loop {
            let end = match self.accept() {
                Ok(stream) => {
                    self.connections.fetch_add(1, Ordering::SeqCst);
                    self.serve(stream)
                }
                Err(end) => end,
            };
            match end {
                LiveEnd::Stopped | LiveEnd::Down(None) => return,
                LiveEnd::ClientLeft => {}
                LiveEnd::Down(Some(d)) => {
                    if !self.down(d) {
                        return;
                    }
                }
            }
        }
    }

    fn stopped(&self) -> bool {
        self.stop.load(Ordering::SeqCst)
    }

    /// The next client; meanwhile the feed's texts are lost and a
    /// disconnection takes the server down.
    fn accept(&self) -> Result<TcpStream, LiveEnd> {
        let Some(listener) = &self.listener else { return Err(LiveEnd::Stopped) };
        while !self.stopped() {
            while let Ok(m) = self.feed.try_recv() {
                if let LiveMessage::Disconnect(d) = m {
                    return Err(LiveEnd::Down(d));
                }
            }
            match listener.accept() {
                Ok((stream, _)) => return Ok(stream),
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => std::thread::sleep(POLL),
                Err(e) => {
                    tracing::warn!("xela_server emulator: accept failed: {e}");
                    std::thread::sleep(POLL);
                }
            }
        }
        Err(LiveEnd::Stopped)
    }

    fn serve(&self, stream: TcpStream) -> LiveEnd {
        let setup = stream
            .set_nonblocking(false)
            .and_then(|()| stream.set_read_timeout(Some(Duration::from_secs(1))))
            .and_then(|()| stream.set_write_timeout(Some(Duration::from_secs(1))));
        if setup.is_err() {
            return LiveEnd::ClientLeft;
        }
        let Ok(mut ws) = tungstenite::accept(stream) else { return LiveEnd::ClientLeft };
        if let Some(welcome) = &self.welcome
            && ws.send(Message::text(welcome.as_str())).is_err()
        {
            return LiveEnd::ClientLeft;
        }
        while !self.stopped() {
            match self.feed.recv_timeout(POLL * 5) {
                Ok(LiveMessage::Text(text)) => {
                    if ws.send(Message::text(text)).is_err() {
                        return LiveEnd::ClientLeft;
                    }
                    self.sent.fetch_add(1, Ordering::SeqCst);
                }
                Ok(LiveMessage::Disconnect(d)) => {
                    // Best effort: the client sees the connection end either way.
                    let _ = ws.get_ref().shutdown(Shutdown::Both);
                    return LiveEnd::Down(d);
                }
                Err(RecvTimeoutError::Timeout) => {}
                Err(RecvTimeoutError::Disconnected) => return self.idle(&mut ws),
            }
        }
        LiveEnd::Stopped
    }

    /// The feed ended: keeps the connection open and silent until the
    /// client leaves or the emulator stops.
    fn idle(&self, ws: &mut WebSocket<TcpStream>) -> LiveEnd {
        if ws.get_ref().set_read_timeout(Some(POLL * 5)).is_err() {
            return LiveEnd::ClientLeft;
        }
        while !self.stopped() {
            match ws.read() {
                Ok(Message::Close(_)) => return LiveEnd::ClientLeft,
                Ok(_) => {}
                Err(WsError::Io(e))
                    if matches!(e.kind(), io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut) => {}
                Err(_) => return LiveEnd::ClientLeft,
            }
        }
        LiveEnd::Stopped
    }

    /// Closes the port for `d` (connections are refused; the feed's texts
    /// are lost), then listens on the same address again. False when
    /// stopped meanwhile or the address cannot be bound again.
    fn down(&mut self, d: Duration) -> bool {
        self.listener = None;
        let until = Instant::now() + d;
        while Instant::now() < until {
            if self.stopped() {
                return false;
            }
            while self.feed.try_recv().is_ok() {}
            std::thread::sleep(POLL);
        }
        let bound = TcpListener::bind(self.addr).and_then(|l| l.set_nonblocking(true).map(|()| l));
        match bound {
            Ok(l) => {
                self.listener = Some(l);
                true
            }
            Err(e) => {
                tracing::warn!("xela_server emulator: cannot listen on {} again: {e}", self.addr);
                false
            }
        }
    }
}
