//! A stand-in for `xela_server` on 127.0.0.1: a WebSocket server that sends
//! the welcome and then replays a script of messages at their pace, with
//! faults on request (dropped connections, a server gone for good; malformed
//! JSON, counter gaps, wrong models and either encoding are the script's
//! content). Only std and tungstenite.

use std::io;
use std::net::{Shutdown, SocketAddr, TcpListener, TcpStream};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use crossbeam_channel::Receiver;
use tungstenite::protocol::Message;
use tungstenite::{Error as WsError, WebSocket};

pub use live::LiveMessage;

use crate::xela_ws::protocol::{
    ExpectedSensor, WireStyle, XelaScan, XelaSensorScan, encode_scan, encode_welcome,
};

mod live;

use live::POLL;

/// One message of the script.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct EmulatedMessage {
    /// Wait before sending it (after the previous message, or the welcome).
    pub delay: Duration,
    /// The text sent, as is (valid or not).
    pub text: String,
}

/// What the emulator sends and the faults of its connection.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct XelaWsEmulatorConfig {
    /// The first message of every connection (`None`: no welcome).
    pub welcome: Option<String>,
    /// The script, sent once across all connections: a new connection goes
    /// on where the previous one stopped. At its end the connection stays
    /// open and silent (a stalled server).
    pub messages: Vec<EmulatedMessage>,
    /// Counts of script messages sent after which the connection is dropped
    /// (TCP shut down without a WebSocket close, as a crashed server).
    pub disconnect_after: Vec<usize>,
    /// Whether a new connection is accepted after a drop. If not, the
    /// server is gone for good at the first drop: the port refuses connections.
    pub accept_reconnect: bool,
}

impl XelaWsEmulatorConfig {
    /// `scans` written in `style`, one every `period`, after the welcome.
    pub fn replay(scans: &[XelaScan], style: WireStyle, period: Duration) -> XelaWsEmulatorConfig {
        let texts = scans.iter().map(|s| encode_scan(s, style)).collect::<Vec<_>>();
        XelaWsEmulatorConfig::texts(texts, period)
    }

    /// `texts` sent as they are, one every `period`, after the welcome.
    pub fn texts(texts: Vec<String>, period: Duration) -> XelaWsEmulatorConfig {
        XelaWsEmulatorConfig {
            welcome: Some(encode_welcome(Some("emulator"))),
            messages: texts.into_iter().map(|text| EmulatedMessage { delay: period, text }).collect(),
            disconnect_after: Vec::new(),
            accept_reconnect: true,
        }
    }
}

/// Scans of `sensors`, with counters `first_message`, `first_message + 1`,
/// ...: raw counts that tell the message, sensor, taxel and axis, server
/// times 10 ms apart, calibrated forces when `calibrated`.
pub fn synthetic_scans(
    first_message: u64,
    count: usize,
    sensors: &[ExpectedSensor],
    calibrated: bool,
) -> Vec<XelaScan> {
    (0..count as u64)
        .map(|i| {
            let message = first_message + i;
            let sensors = sensors.iter().map(|s| synthetic_sensor(message, s, calibrated)).collect();
            XelaScan { message, server_time_s: Some(1.7e9 + 0.01 * message as f64), sensors }
        })
        .collect()
}

fn synthetic_sensor(message: u64, s: &ExpectedSensor, calibrated: bool) -> XelaSensorScan {
    let count =
        |t: usize, axis: u16| (32768 + 1000 * s.sensor as u64 + 10 * t as u64 + message % 5000) as u16 + axis;
    let taxels = (0..s.taxels).map(|t| [count(t, 0), count(t, 1), count(t, 2)]).collect();
    let force = |t: usize, axis: usize| (message % 100) as f64 * 0.01 + t as f64 * 0.001 - axis as f64 * 0.5;
    let forces = (0..s.taxels).map(|t| [force(t, 0), force(t, 1), force(t, 2)]).collect();
    XelaSensorScan {
        sensor: s.sensor,
        model: s.model.clone(),
        time_s: Some(1.7e9 + 0.01 * message as f64 - 0.002),
        taxels,
        calibrated: calibrated.then_some(forces),
    }
}

/// The running emulator; dropping it stops it and closes its port.
pub struct XelaWsEmulator {
    addr: SocketAddr,
    stop: Arc<AtomicBool>,
    sent: Arc<AtomicUsize>,
    connections: Arc<AtomicUsize>,
    thread: Option<JoinHandle<()>>,
}

impl XelaWsEmulator {
    /// Listens on 127.0.0.1 on a free port and serves `config` on a thread
    /// named `xela-ws-emulator`.
    pub fn start(config: XelaWsEmulatorConfig) -> io::Result<XelaWsEmulator> {
        XelaWsEmulator::bind(SocketAddr::from(([127, 0, 0, 1], 0)), config)
    }

    /// Listens on `addr` (port 0: any free port) and serves `config`.
    pub fn bind(addr: SocketAddr, config: XelaWsEmulatorConfig) -> io::Result<XelaWsEmulator> {
        XelaWsEmulator::serve(addr, |listener, _, stop, sent, connections| {
            let server = Server { listener, config, stop, sent, connections };
            move || server.run()
        })
    }

    /// Listens on 127.0.0.1 on a free port and sends what `feed` brings as
    /// it comes, after `welcome` on each connection (see [`LiveMessage`]).
    pub fn start_live(welcome: Option<String>, feed: Receiver<LiveMessage>) -> io::Result<XelaWsEmulator> {
        let localhost = SocketAddr::from(([127, 0, 0, 1], 0));
        XelaWsEmulator::serve(localhost, |listener, addr, stop, sent, connections| {
            let server =
                live::LiveServer { listener: Some(listener), addr, welcome, feed, stop, sent, connections };
            move || server.run()
        })
    }

    /// Binds a non-blocking listener on `addr` and runs the server that
    /// `make` builds from it (listener, bound address, stop flag, counters
    /// of messages sent and connections) on a thread named `xela-ws-emulator`.
    fn serve<R: FnOnce() + Send + 'static>(
        addr: SocketAddr,
        make: impl FnOnce(TcpListener, SocketAddr, Arc<AtomicBool>, Arc<AtomicUsize>, Arc<AtomicUsize>) -> R,
    ) -> io::Result<XelaWsEmulator> {
        let listener = TcpListener::bind(addr)?;
        listener.set_nonblocking(true)?;
        let addr = listener.local_addr()?;
        let stop = Arc::new(AtomicBool::new(false));
        let sent = Arc::new(AtomicUsize::new(0));
        let connections = Arc::new(AtomicUsize::new(0));
        let run = make(listener, addr, Arc::clone(&stop), Arc::clone(&sent), Arc::clone(&connections));
        let thread = std::thread::Builder::new().name("xela-ws-emulator".into()).spawn(run)?;
        Ok(XelaWsEmulator { addr, stop, sent, connections, thread: Some(thread) })
    }

    /// The address it listens on.
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    /// `ws://127.0.0.1:PORT`, for the client.
    pub fn url(&self) -> String {
        format!("ws://{}", self.addr)
    }

    /// Script messages sent so far.
    pub fn sent(&self) -> usize {
        self.sent.load(Ordering::SeqCst)
    }

    /// Connections accepted so far.
    pub fn connections(&self) -> usize {
        self.connections.load(Ordering::SeqCst)
    }
}

impl Drop for XelaWsEmulator {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        if let Some(t) = self.thread.take()
            && t.join().is_err()
        {
            tracing::warn!("xela_server emulator on {}: its thread panicked", self.addr);
        }
    }
}

/// How a connection ended.
enum End {
    /// The emulator was stopped.
    Stopped,
    /// A planned drop (`disconnect_after`).
    Dropped,
    /// The client went away (or the handshake failed).
    ClientLeft,
}

struct Server {
    listener: TcpListener,
    config: XelaWsEmulatorConfig,
    stop: Arc<AtomicBool>,
    sent: Arc<AtomicUsize>,
    connections: Arc<AtomicUsize>,
}

impl Server {
    fn run(self) {
        let mut next = 0;
        while let Some(stream) = self.accept() {
            self.connections.fetch_add(1, Ordering::SeqCst);
            match self.serve(stream, &mut next) {
                End::Stopped => return,
                End::Dropped if !self.config.accept_reconnect => return, // drops the listener
                End::Dropped | End::ClientLeft => {}
            }
        }
    }

    fn stopped(&self) -> bool {
        self.stop.load(Ordering::SeqCst)
    }

    fn accept(&self) -> Option<TcpStream> {
        while !self.stopped() {
            match self.listener.accept() {
                Ok((stream, _)) => return Some(stream),
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => std::thread::sleep(POLL),
                Err(e) => {
                    tracing::warn!("xela_server emulator: accept failed: {e}");
                    std::thread::sleep(POLL);
                }
            }
        }
        None
    }

    /// Sends the welcome and the script from message `next` on one connection.
    fn serve(&self, stream: TcpStream, next: &mut usize) -> End {
        let setup = stream
            .set_nonblocking(false)
            .and_then(|()| stream.set_read_timeout(Some(Duration::from_secs(1))))
            .and_then(|()| stream.set_write_timeout(Some(Duration::from_secs(1))));
        if let Err(e) = setup {
            tracing::warn!("xela_server emulator: {e}");
            return End::ClientLeft;
        }
        let Ok(mut ws) = tungstenite::accept(stream) else { return End::ClientLeft };
        if let Some(welcome) = &self.config.welcome
            && ws.send(Message::text(welcome.as_str())).is_err()
        {
            return End::ClientLeft;
        }
        while let Some(message) = self.config.messages.get(*next) {
            if !self.wait(message.delay) {
                return End::Stopped;
            }
            if ws.send(Message::text(message.text.as_str())).is_err() {
                return End::ClientLeft;
            }
            *next += 1;
            self.sent.fetch_add(1, Ordering::SeqCst);
            if self.config.disconnect_after.contains(next) {
                // Best effort: the client sees the connection end either way.
                let _ = ws.get_ref().shutdown(Shutdown::Both);
                return End::Dropped;
            }
        }
        self.idle(&mut ws)
    }

    /// Keeps a connection open and silent until the client leaves or the
    /// emulator stops; answers pings.
    fn idle(&self, ws: &mut WebSocket<TcpStream>) -> End {
        if ws.get_ref().set_read_timeout(Some(POLL * 5)).is_err() {
            return End::ClientLeft;
        }
        while !self.stopped() {
            match ws.read() {
                Ok(Message::Close(_)) => return End::ClientLeft,
                Ok(_) => {}
                Err(WsError::Io(e))
                    if matches!(e.kind(), io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut) => {}
                Err(_) => return End::ClientLeft,
            }
        }
        End::Stopped
    }

    /// Sleeps `delay` in short steps; false when stopped meanwhile.
    fn wait(&self, delay: Duration) -> bool {
        let until = Instant::now() + delay;
        loop {
            if self.stopped() {
                return false;
            }
            let left = until.saturating_duration_since(Instant::now());
            if left.is_zero() {
                return true;
            }
            std::thread::sleep(left.min(POLL));
        }
    }
}
