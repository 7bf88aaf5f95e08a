//! The live view's front door: viewers that speak the open Foxglove
//! WebSocket protocol (`foxglove.websocket.v1`) as well as the SDK's own
//! subprotocols.
//!
//! The Foxglove SDK's server (crate `foxglove` 0.30) negotiates only
//! `foxglove.sdk.v1` and `foxglove.sdk.v1.1` and answers any other offer with
//! HTTP 400, and it has no hook to change that. The protocol's
//! specification (foxglove/ws-protocol, `docs/spec.md`) names the
//! subprotocol `foxglove.websocket.v1`, which the official
//! `@foxglove/ws-protocol` client offers. `foxglove.sdk.v1` is that same
//! protocol under a new name: advertisements carry their schemas inline,
//! message data is opcode 1 with a subscription id and a receive time (see
//! `docs/protocols.md`). `foxglove.sdk.v1.1` is not (it advertises schemas
//! through a per-connection table).
//!
//! So the front door listens on the live view's address and relays every
//! connection to the SDK's server on loopback. A viewer that offers
//! `foxglove.sdk.v1` or `foxglove.sdk.v1.1` is relayed unchanged. A viewer
//! that offers only `foxglove.websocket.v1` (of the known ones) has its
//! offer replaced by `foxglove.sdk.v1` in the handshake, and the server's
//! answer renamed back to `foxglove.websocket.v1`; after the handshake the
//! bytes are relayed untouched. Anything else is relayed unchanged and the
//! SDK refuses it.
//!
//! The relay runs on the live view's background runtime (nice 19) and holds
//! at most its copy buffers per connection: a viewer that does not read
//! stops the relay writing to it, which stops it reading from the SDK,
//! whose per-viewer queue then drops the oldest messages, as without the
//! front door. The recording never waits for any of it.

use std::io;
use std::net::SocketAddr;

use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::{TcpListener, TcpStream};

/// The subprotocol of the open specification (foxglove/ws-protocol).
pub(crate) const OPEN_SUBPROTOCOL: &str = "foxglove.websocket.v1";
/// The SDK's name for the same protocol.
pub(crate) const SDK_SUBPROTOCOL: &str = "foxglove.sdk.v1";
/// The SDK's schema-table variant (not the open protocol).
const SDK_SUBPROTOCOL_V1_1: &str = "foxglove.sdk.v1.1";

/// Where the SDK's server listens, behind the front door.
pub(crate) const BACKEND_HOST: &str = "127.0.0.1";

/// The SDK's server's address behind the front door, from its port.
pub(crate) fn backend_addr(port: u16) -> SocketAddr {
    SocketAddr::from(([127, 0, 0, 1], port))
}

/// Longest HTTP head (request or response) the front door reads; a longer
/// one closes the connection.
const MAX_HEAD_BYTES: usize = 16 * 1024;

/// Serves viewers on `listener`, relaying each to the SDK's server at
/// `backend`, until the task is aborted.
pub(crate) async fn serve(listener: TcpListener, backend: SocketAddr) {
    loop {
        let viewer = match listener.accept().await {
            Ok((viewer, _)) => viewer,
            Err(e) => {
                tracing::debug!("live: accepting a viewer failed: {e}");
                continue;
            }
        };
        tokio::spawn(async move {
            if let Err(e) = relay(viewer, backend).await {
                tracing::debug!("live: viewer connection ended: {e}");
            }
        });
    }
}

/// Relays one viewer's connection (see the module's documentation).
async fn relay(mut viewer: TcpStream, backend: SocketAddr) -> io::Result<()> {
    let _ = viewer.set_nodelay(true);
    let (head, rest) = read_head(&mut viewer).await?;
    let (request, renamed) = rewrite_request(&head);
    let mut server = TcpStream::connect(backend).await?;
    let _ = server.set_nodelay(true);
    server.write_all(request.as_bytes()).await?;
    server.write_all(&rest).await?;
    if renamed {
        let (answer, after) = read_head(&mut server).await?;
        viewer.write_all(rewrite_response(&answer).as_bytes()).await?;
        viewer.write_all(&after).await?;
    }
    tokio::io::copy_bidirectional(&mut viewer, &mut server).await?;
    Ok(())
}

/// Reads an HTTP head (up to and including the empty line) from `stream`;
/// returns it and the bytes read after it.
async fn read_head(stream: &mut TcpStream) -> io::Result<(String, Vec<u8>)> {
    let mut buf = Vec::with_capacity(1024);
    let mut chunk = [0u8; 2048];
    loop {
        if let Some(end) = buf.windows(4).position(|w| w == b"\r\n\r\n") {
            let rest = buf.split_off(end + 4);
            let head = String::from_utf8(buf)
                .map_err(|_| io::Error::new(io::ErrorKind::InvalidData, "HTTP head is not UTF-8"))?;
            return Ok((head, rest));
        }
        if buf.len() > MAX_HEAD_BYTES {
            return Err(io::Error::new(io::ErrorKind::InvalidData, "HTTP head too long"));
        }
        let n = stream.read(&mut chunk).await?;
        if n == 0 {
            return Err(io::Error::new(io::ErrorKind::UnexpectedEof, "connection closed in the HTTP head"));
        }
        buf.extend_from_slice(&chunk[..n]);
    }
}

/// Whether `line` is a `Sec-WebSocket-Protocol` header; its value if so.
fn protocol_header(line: &str) -> Option<&str> {
    let (name, value) = line.split_once(':')?;
    name.trim().eq_ignore_ascii_case("sec-websocket-protocol").then_some(value)
}

/// The request head to send to the SDK, and whether the offer was renamed
/// (the viewer offers `foxglove.websocket.v1` and none of the SDK's names).
pub(crate) fn rewrite_request(head: &str) -> (String, bool) {
    let offered: Vec<&str> =
        head.split("\r\n").filter_map(protocol_header).flat_map(|v| v.split(',')).map(str::trim).collect();
    let sdk = offered.iter().any(|p| *p == SDK_SUBPROTOCOL || *p == SDK_SUBPROTOCOL_V1_1);
    if sdk || !offered.contains(&OPEN_SUBPROTOCOL) {
        return (head.to_string(), false);
    }
    let mut out = String::with_capacity(head.len());
    let mut replaced = false;
    for line in head.strip_suffix("\r\n\r\n").unwrap_or(head).split("\r\n") {
        if protocol_header(line).is_some() {
            if !replaced {
                out.push_str("Sec-WebSocket-Protocol: ");
                out.push_str(SDK_SUBPROTOCOL);
                out.push_str("\r\n");
                replaced = true;
            }
            continue;
        }
        out.push_str(line);
        out.push_str("\r\n");
    }
    out.push_str("\r\n");
    (out, true)
}

/// The SDK's answer with its chosen subprotocol (`foxglove.sdk.v1`) named
/// `foxglove.websocket.v1` again; any other answer (a refusal) unchanged.
pub(crate) fn rewrite_response(head: &str) -> String {
    let lines: Vec<String> = head
        .strip_suffix("\r\n\r\n")
        .unwrap_or(head)
        .split("\r\n")
        .map(|line| match protocol_header(line) {
            Some(value) if value.trim() == SDK_SUBPROTOCOL => {
                format!("Sec-WebSocket-Protocol: {OPEN_SUBPROTOCOL}")
            }
            _ => line.to_string(),
        })
        .collect();
    format!("{}\r\n\r\n", lines.join("\r\n"))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn request(protocols: &[&str]) -> String {
        let mut head = "GET / HTTP/1.1\r\nHost: x\r\nUpgrade: websocket\r\n".to_string();
        for p in protocols {
            head.push_str(&format!("Sec-WebSocket-Protocol: {p}\r\n"));
        }
        head + "Sec-WebSocket-Key: k\r\n\r\n"
    }

    #[test]
    fn an_open_protocol_offer_becomes_the_sdks_v1_and_nothing_else_changes() {
        let (out, renamed) = rewrite_request(&request(&["foxglove.websocket.v1"]));
        assert!(renamed);
        assert_eq!(out, request(&["foxglove.sdk.v1"]));
        // Several offers over two header lines: one line, v1 (never v1.1).
        let (out, renamed) = rewrite_request(&request(&["other, foxglove.websocket.v1", "more"]));
        assert!(renamed);
        assert_eq!(out, request(&["foxglove.sdk.v1"]));
        // Header names are case-insensitive.
        let (out, renamed) = rewrite_request(&request(&[]).replace(
            "Sec-WebSocket-Key",
            "sec-websocket-protocol:  foxglove.websocket.v1\r\nSec-WebSocket-Key",
        ));
        assert!(renamed);
        assert_eq!(
            out,
            request(&[])
                .replace("Sec-WebSocket-Key", "Sec-WebSocket-Protocol: foxglove.sdk.v1\r\nSec-WebSocket-Key")
        );
    }

    #[test]
    fn sdk_offers_and_unknown_offers_pass_unchanged() {
        for offer in [
            vec!["foxglove.sdk.v1"],
            vec!["foxglove.sdk.v1.1"],
            vec!["foxglove.websocket.v1, foxglove.sdk.v1.1"],
            vec!["foxglove.websocket.v10"],
            vec!["foxglove.websocket"],
            vec![],
        ] {
            let head = request(&offer);
            assert_eq!(rewrite_request(&head), (head.clone(), false), "{offer:?}");
        }
    }

    #[test]
    fn the_answer_names_the_open_protocol_and_a_refusal_stays_one() {
        let ok = "HTTP/1.1 101 Switching Protocols\r\nsec-websocket-protocol: foxglove.sdk.v1\r\nupgrade: websocket\r\n\r\n";
        assert_eq!(
            rewrite_response(ok),
            "HTTP/1.1 101 Switching Protocols\r\nSec-WebSocket-Protocol: foxglove.websocket.v1\r\nupgrade: websocket\r\n\r\n"
        );
        let refused = "HTTP/1.1 400 Bad Request\r\ncontent-length: 3\r\n\r\n";
        assert_eq!(rewrite_response(refused), refused);
    }
}
