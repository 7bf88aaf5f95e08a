//! A blocking client of `xela_server`'s WebSocket: the socket only moves
//! text messages into a [`XelaDecoder`]; a lost connection is re-established
//! with exponential backoff.

use std::net::{TcpStream, ToSocketAddrs};
use std::time::{Duration, Instant};

use slidetrack_core::{DeviceError, ErrorKind};
use tungstenite::client::IntoClientRequest;
use tungstenite::handshake::HandshakeError;
use tungstenite::protocol::{Message, WebSocketConfig};
use tungstenite::{Error as WsError, WebSocket};

use crate::xela_ws::protocol::{
    DEFAULT_PORT, Expected, MessageGap, XelaCounters, XelaDecoder, XelaError, XelaEvent, XelaScan,
    XelaWelcome,
};

/// How a lost connection is re-established.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ReconnectPolicy {
    /// Wait before the second attempt; the first one is immediate.
    pub initial_backoff: Duration,
    /// Longest wait between two attempts (each wait doubles up to it).
    pub max_backoff: Duration,
    /// Attempts after which the server counts as gone (0: never reconnect).
    pub max_attempts: u32,
    /// Time after the loss after which the server counts as gone.
    pub max_duration: Duration,
}

impl Default for ReconnectPolicy {
    /// 10 attempts within 10 s, waits from 100 ms doubling up to 2 s (the
    /// server takes a few seconds to start).
    fn default() -> Self {
        ReconnectPolicy {
            initial_backoff: Duration::from_millis(100),
            max_backoff: Duration::from_secs(2),
            max_attempts: 10,
            max_duration: Duration::from_secs(10),
        }
    }
}

impl ReconnectPolicy {
    /// The wait after `failed` failed attempts: `initial_backoff × 2^(failed − 1)`,
    /// at most `max_backoff`.
    pub fn backoff(&self, failed: u32) -> Duration {
        let doublings = failed.saturating_sub(1).min(20);
        self.initial_backoff.saturating_mul(1 << doublings).min(self.max_backoff)
    }

    fn exhausted(&self, attempts: u32, since: Instant) -> bool {
        attempts >= self.max_attempts || since.elapsed() >= self.max_duration
    }
}

/// How the client connects.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct XelaWsOptions {
    /// The sensors the rig expects; a data message that does not match is a
    /// final error. `None`: whatever the server sends.
    pub expected: Option<Expected>,
    /// Limit of one TCP connection and WebSocket handshake.
    pub connect_timeout: Duration,
    /// Reconnection, also used for the first connection.
    pub reconnect: ReconnectPolicy,
    /// Longest message accepted (bytes).
    pub max_message_bytes: usize,
}

impl Default for XelaWsOptions {
    fn default() -> Self {
        XelaWsOptions {
            expected: None,
            connect_timeout: Duration::from_secs(1),
            reconnect: ReconnectPolicy::default(),
            max_message_bytes: 4 << 20,
        }
    }
}

/// A scan and when it arrived.
#[derive(Clone, Debug, PartialEq)]
pub struct XelaReceived {
    /// When the message that carried it had been read from the socket.
    pub arrival: Instant,
    /// The scan (its `server_time_s` as the server wrote it).
    pub scan: XelaScan,
    /// The break in the server's message counter before it, if any.
    pub gap: Option<MessageGap>,
}

enum Link {
    Up(Box<WebSocket<TcpStream>>),
    Down(Outage),
}

struct Outage {
    since: Instant,
    attempts: u32,
    next_attempt: Instant,
    last_error: String,
}

/// A client of one `xela_server`.
pub struct XelaWsClient {
    url: String,
    options: XelaWsOptions,
    decoder: XelaDecoder,
    link: Link,
    welcome: Option<XelaWelcome>,
    reconnects: u64,
    failed: Option<DeviceError>,
}

impl XelaWsClient {
    /// Connects to `url` (`ws://HOST[:PORT]`, port 5000 when none is given),
    /// retrying as `options.reconnect` allows: the server takes a few seconds
    /// to start. `Disconnected` when it cannot be reached, `Other` for a URL
    /// this client cannot use (`wss://`: it is built without TLS).
    pub fn connect(url: &str, options: XelaWsOptions) -> Result<XelaWsClient, DeviceError> {
        target(url)?;
        let now = Instant::now();
        let outage = Outage { since: now, attempts: 0, next_attempt: now, last_error: String::new() };
        let mut client = XelaWsClient {
            url: url.to_string(),
            decoder: XelaDecoder::new(options.expected.clone()),
            options,
            link: Link::Down(outage),
            welcome: None,
            reconnects: 0,
            failed: None,
        };
        let first = ReconnectPolicy {
            max_attempts: client.options.reconnect.max_attempts.max(1),
            ..client.options.reconnect
        };
        let connected = client.restore(first, None);
        connected.map_err(|e| DeviceError { detail: connect_hint(&e.detail), ..e })?;
        client.reconnects = 0;
        client.failed = None;
        Ok(client)
    }

    /// The next scan.
    ///
    /// # Contract
    /// - Blocks until a data message decodes into a scan and returns it with
    ///   its arrival instant; the welcome is skipped; malformed messages are
    ///   counted and skipped.
    /// - `Timeout` when no scan arrives within `timeout`, also while the
    ///   connection is being re-established (the next call goes on with it).
    /// - A lost connection is re-established as the [`ReconnectPolicy`]
    ///   allows; when it cannot be, `Disconnected`. A connection attempt
    ///   under way may hold the call up to `connect_timeout` past `timeout`.
    /// - A scan that does not match the expected sensors is an `Other`
    ///   error naming the sensor and the setting.
    /// - After a `Disconnected` or mismatch error every call fails with it.
    pub fn next_scan(&mut self, timeout: Duration) -> Result<XelaReceived, DeviceError> {
        if let Some(e) = &self.failed {
            return Err(e.clone());
        }
        let deadline = Instant::now() + timeout;
        loop {
            let ws = match &mut self.link {
                Link::Up(ws) => ws,
                Link::Down(_) => {
                    self.restore(self.options.reconnect, Some((deadline, timeout)))?;
                    continue;
                }
            };
            let remaining = deadline.saturating_duration_since(Instant::now());
            if remaining.is_zero() {
                return Err(self.timeout_error(timeout));
            }
            if let Err(e) = ws.get_ref().set_read_timeout(Some(remaining)) {
                self.lose(format!("cannot set the read timeout: {e}"));
                continue;
            }
            match ws.read() {
                Ok(Message::Text(text)) => {
                    if let Some(received) = self.on_text(&text, Instant::now())? {
                        return Ok(received);
                    }
                }
                Ok(Message::Binary(bytes)) => {
                    let e = self.decoder.reject_binary(bytes.len());
                    tracing::debug!("{}: {e}", self.url);
                }
                Ok(Message::Close(frame)) => {
                    self.lose(format!("the server closed the connection ({frame:?})"))
                }
                Ok(_) => {}
                Err(WsError::Io(e)) if is_timeout(&e) => {}
                Err(e) => self.lose(e.to_string()),
            }
        }
    }

    /// The counters: the decoder's, with the reconnections.
    pub fn counters(&self) -> XelaCounters {
        XelaCounters { reconnects: self.reconnects, ..self.decoder.counters() }
    }

    /// Whether the connection is up: false while it is being re-established
    /// (and after a final error).
    pub fn connected(&self) -> bool {
        self.failed.is_none() && matches!(self.link, Link::Up(_))
    }

    /// The URL connected to.
    pub fn url(&self) -> &str {
        &self.url
    }

    /// The last welcome message received, if any.
    pub fn welcome(&self) -> Option<&XelaWelcome> {
        self.welcome.as_ref()
    }

    fn on_text(&mut self, text: &str, arrival: Instant) -> Result<Option<XelaReceived>, DeviceError> {
        match self.decoder.decode(text) {
            Ok(decoded) => match decoded.event {
                XelaEvent::Welcome(welcome) => {
                    tracing::debug!("{}: welcome {welcome:?}", self.url);
                    self.welcome = Some(welcome);
                    Ok(None)
                }
                XelaEvent::Data(scan) => {
                    if let Some(gap) = decoded.gap {
                        tracing::debug!("{}: message counter break {gap:?}", self.url);
                    }
                    Ok(Some(XelaReceived { arrival, scan, gap: decoded.gap }))
                }
            },
            Err(XelaError::Malformed(e)) => {
                tracing::debug!("{}: skipped a malformed message: {e}", self.url);
                Ok(None)
            }
            Err(XelaError::Mismatch(m)) => {
                let e = DeviceError::new(ErrorKind::Other, &self.url, m.to_string());
                self.failed = Some(e.clone());
                Err(e)
            }
        }
    }

    /// Drops the connection; the next read reconnects.
    fn lose(&mut self, why: String) {
        tracing::warn!("{}: connection lost: {why}", self.url);
        let now = Instant::now();
        self.link = Link::Down(Outage { since: now, attempts: 0, next_attempt: now, last_error: why });
    }

    /// Re-establishes the connection as `policy` allows, waiting no later
    /// than `deadline` (the scan's, with its timeout for messages) if one is
    /// given.
    fn restore(
        &mut self,
        policy: ReconnectPolicy,
        deadline: Option<(Instant, Duration)>,
    ) -> Result<(), DeviceError> {
        let Link::Down(outage) = &mut self.link else { return Ok(()) };
        loop {
            if policy.exhausted(outage.attempts, outage.since) {
                let detail = format!(
                    "server unreachable: {} connection attempts in {} ms failed, the last: {}",
                    outage.attempts,
                    outage.since.elapsed().as_millis(),
                    outage.last_error
                );
                let e = DeviceError::new(ErrorKind::Disconnected, &self.url, detail);
                self.failed = Some(e.clone());
                return Err(e);
            }
            let now = Instant::now();
            if let Some((deadline, timeout)) = deadline
                && outage.next_attempt >= deadline
            {
                std::thread::sleep(deadline.saturating_duration_since(now));
                let detail = format!(
                    "no scan within {} ms: reconnecting after {} failed attempts ({})",
                    timeout.as_millis(),
                    outage.attempts,
                    outage.last_error
                );
                return Err(DeviceError::new(ErrorKind::Timeout, &self.url, detail));
            }
            std::thread::sleep(outage.next_attempt.saturating_duration_since(now));
            match open(&self.url, &self.options) {
                Ok(ws) => {
                    tracing::info!("{}: connected after {} failed attempts", self.url, outage.attempts);
                    self.link = Link::Up(Box::new(ws));
                    self.reconnects += 1;
                    return Ok(());
                }
                Err(why) => {
                    outage.attempts += 1;
                    outage.next_attempt = Instant::now() + policy.backoff(outage.attempts);
                    outage.last_error = why;
                }
            }
        }
    }

    fn timeout_error(&self, waited: Duration) -> DeviceError {
        let c = self.counters();
        let why = if c.messages == 0 {
            format!("no message within {} ms: is xela_server reading the sensors?", waited.as_millis())
        } else {
            format!("no scan within {} ms ({c})", waited.as_millis())
        };
        DeviceError::new(ErrorKind::Timeout, &self.url, why)
    }
}

/// Host and port of a `ws://` URL.
fn target(url: &str) -> Result<(String, u16), DeviceError> {
    let bad = |why: String| DeviceError::new(ErrorKind::Other, url, why);
    let request = url.into_client_request().map_err(|e| bad(format!("not a WebSocket URL: {e}")))?;
    let uri = request.uri();
    match uri.scheme_str() {
        Some("ws") => {}
        Some("wss") => {
            return Err(bad("wss:// needs TLS, which this client is built without: use ws://".into()));
        }
        _ => return Err(bad("not a ws:// URL".into())),
    }
    let host = uri.host().ok_or_else(|| bad("the URL has no host".into()))?;
    let host = host.trim_start_matches('[').trim_end_matches(']').to_string();
    Ok((host, uri.port_u16().unwrap_or(DEFAULT_PORT)))
}

/// One TCP connection and WebSocket handshake, within `options.connect_timeout`.
fn open(url: &str, options: &XelaWsOptions) -> Result<WebSocket<TcpStream>, String> {
    let (host, port) = target(url).map_err(|e| e.detail)?;
    let addrs = (host.as_str(), port).to_socket_addrs().map_err(|e| format!("cannot resolve {host}: {e}"))?;
    let mut last = format!("{host} has no address");
    let mut stream = None;
    for addr in addrs {
        match TcpStream::connect_timeout(&addr, options.connect_timeout) {
            Ok(s) => {
                stream = Some(s);
                break;
            }
            Err(e) => last = format!("cannot connect to {addr}: {e}"),
        }
    }
    let stream = stream.ok_or(last)?;
    let setup = |s: &TcpStream| {
        s.set_nodelay(true)?;
        s.set_read_timeout(Some(options.connect_timeout))?;
        s.set_write_timeout(Some(options.connect_timeout))
    };
    setup(&stream).map_err(|e| format!("cannot set up the socket: {e}"))?;
    let config = WebSocketConfig::default()
        .max_message_size(Some(options.max_message_bytes))
        .max_frame_size(Some(options.max_message_bytes));
    let request = url.into_client_request().map_err(|e| e.to_string())?;
    match tungstenite::client::client_with_config(request, stream, Some(config)) {
        Ok((ws, _response)) => Ok(ws),
        Err(HandshakeError::Failure(e)) => Err(format!("WebSocket handshake failed: {e}")),
        Err(HandshakeError::Interrupted(_)) => Err("WebSocket handshake timed out".into()),
    }
}

fn is_timeout(e: &std::io::Error) -> bool {
    matches!(
        e.kind(),
        std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut | std::io::ErrorKind::Interrupted
    )
}

/// What to check when the first connection fails.
fn connect_hint(detail: &str) -> String {
    format!(
        "{detail} (is xela_server running, and listening on this address? It binds the address given \
         with --ip and the port given with --port, 5000 by default)"
    )
}

#[cfg(test)]
mod tests;
