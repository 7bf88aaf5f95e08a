//! [`StalledViewer`]: the worst viewer, for benchmarks and tests.

use std::collections::BTreeSet;
use std::net::{SocketAddr, TcpStream};
use std::time::{Duration, Instant};

use tungstenite::client::IntoClientRequest;
use tungstenite::http::HeaderValue;
use tungstenite::{Message, WebSocket};

use super::error::LiveError;

/// The Foxglove WebSocket subprotocol the probe speaks (channels advertised
/// with their schemas inline).
const SUBPROTOCOL: &str = "foxglove.sdk.v1";

/// A viewer that connects, subscribes to every channel advertised while it
/// waits, and then never reads again: its socket and the server's queue for
/// it fill up. Dropping it closes the connection.
pub struct StalledViewer {
    _socket: WebSocket<TcpStream>,
    subscribed: BTreeSet<u64>,
}

impl StalledViewer {
    /// Connects to the live view at `addr`, reads advertisements until
    /// `min_channels` channels are known (or `timeout` passes), subscribes to
    /// all of them, and stops reading.
    pub fn subscribe_all(
        addr: SocketAddr,
        min_channels: usize,
        timeout: Duration,
    ) -> Result<StalledViewer, LiveError> {
        let probe = |e: &dyn std::fmt::Display| LiveError::Probe(format!("ws://{addr}: {e}"));
        let stream = TcpStream::connect_timeout(&addr, timeout).map_err(|e| probe(&e))?;
        // The whole timeout for the handshake (the server's threads run at
        // nice 19 and answer late on a busy machine), then short reads.
        stream.set_read_timeout(Some(timeout)).map_err(|e| probe(&e))?;
        let mut request = format!("ws://{addr}/").into_client_request().map_err(|e| probe(&e))?;
        request.headers_mut().insert("Sec-WebSocket-Protocol", HeaderValue::from_static(SUBPROTOCOL));
        let (mut socket, _) = tungstenite::client(request, stream).map_err(|e| probe(&e))?;
        socket.get_ref().set_read_timeout(Some(Duration::from_millis(50))).map_err(|e| probe(&e))?;
        let deadline = Instant::now() + timeout;
        let mut channels = BTreeSet::new();
        while channels.len() < min_channels && Instant::now() < deadline {
            match socket.read() {
                Ok(Message::Text(text)) => channels.extend(advertised(&text)),
                Ok(_) => {}
                Err(tungstenite::Error::Io(e))
                    if matches!(e.kind(), std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut) => {}
                Err(e) => return Err(probe(&e)),
            }
        }
        let subscriptions: Vec<_> = channels
            .iter()
            .enumerate()
            .map(|(k, id)| serde_json::json!({ "id": k + 1, "channelId": id }))
            .collect();
        let subscribe = serde_json::json!({ "op": "subscribe", "subscriptions": subscriptions });
        socket.send(Message::text(subscribe.to_string())).map_err(|e| probe(&e))?;
        Ok(StalledViewer { _socket: socket, subscribed: channels })
    }

    /// The channel ids it subscribed to.
    pub fn subscribed(&self) -> &BTreeSet<u64> {
        &self.subscribed
    }
}

/// The channel ids of an `advertise` message (none for other messages).
fn advertised(text: &str) -> Vec<u64> {
    let Ok(value) = serde_json::from_str::<serde_json::Value>(text) else { return Vec::new() };
    if value["op"] != "advertise" {
        return Vec::new();
    }
    value["channels"]
        .as_array()
        .map_or_else(Vec::new, |cs| cs.iter().filter_map(|c| c["id"].as_u64()).collect())
}
