//! The socket side of the external source: a listener thread that accepts
//! one client at a time and a reader thread per connection, which decode
//! lines and pass them on as [`Event`]s.

use std::io::{BufRead, BufReader, Read, Write};
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::Sender;
use std::sync::{Arc, Mutex, PoisonError};
use std::thread;
use std::time::Duration;

use super::protocol::{
    ClientMessage, ExternalError, MAX_LINE_BYTES, ServerMessage, check_hello, decode_line,
};

/// What the socket threads report to the source.
#[derive(Debug)]
pub(super) enum Event {
    /// A client finished its handshake.
    Connected,
    /// A result message.
    Result(ClientMessage),
    /// A refused message or a broken connection.
    Error(ExternalError),
    /// The client left.
    Disconnected,
}

/// The connected client's stream, for the server's messages.
#[derive(Clone, Default)]
pub(super) struct Writer(Arc<Mutex<Option<TcpStream>>>);

impl Writer {
    /// Sends `message` to the client, if one is connected; a failed write
    /// drops the client (its reader thread sees the end).
    pub(super) fn send(&self, message: &ServerMessage) {
        let mut guard = self.0.lock().unwrap_or_else(PoisonError::into_inner);
        let Some(stream) = guard.as_mut() else { return };
        let Ok(mut line) = serde_json::to_vec(message) else { return };
        line.push(b'\n');
        if stream.write_all(&line).is_err()
            && let Some(s) = guard.take()
        {
            let _ = s.shutdown(std::net::Shutdown::Both);
        }
    }

    /// Closes the client's connection.
    pub(super) fn close(&self) {
        self.replace(None);
    }

    fn replace(&self, stream: Option<TcpStream>) {
        let mut guard = self.0.lock().unwrap_or_else(PoisonError::into_inner);
        if let Some(old) = guard.take() {
            let _ = old.shutdown(std::net::Shutdown::Both);
        }
        *guard = stream;
    }

    /// Whether a client is connected.
    pub(super) fn is_connected(&self) -> bool {
        self.0.lock().unwrap_or_else(PoisonError::into_inner).is_some()
    }
}

/// Listens on `addr`; returns the bound address. The listener thread stops
/// when `stop` is set.
pub(super) fn listen(
    addr: &str,
    hello: ServerMessage,
    writer: Writer,
    events: Sender<Event>,
    stop: Arc<AtomicBool>,
) -> Result<SocketAddr, ExternalError> {
    let error = |source| ExternalError::Listen { addr: addr.to_string(), source };
    let listener = TcpListener::bind(addr).map_err(error)?;
    listener.set_nonblocking(true).map_err(error)?;
    let local = listener.local_addr().map_err(error)?;
    thread::Builder::new()
        .name("external-source-listen".into())
        .spawn(move || accept_loop(&listener, &hello, &writer, &events, &stop))
        .map_err(error)?;
    Ok(local)
}

fn accept_loop(
    listener: &TcpListener,
    hello: &ServerMessage,
    writer: &Writer,
    events: &Sender<Event>,
    stop: &AtomicBool,
) {
    while !stop.load(Ordering::Relaxed) {
        let stream = match listener.accept() {
            Ok((stream, _)) => stream,
            Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {
                thread::sleep(Duration::from_millis(5));
                continue;
            }
            Err(e) => {
                tracing::warn!("external source: accept failed: {e}");
                thread::sleep(Duration::from_millis(50));
                continue;
            }
        };
        let (Ok(()), Ok(reading)) = (stream.set_nonblocking(false), stream.try_clone()) else { continue };
        // A new client replaces the old one.
        writer.replace(Some(stream));
        writer.send(hello);
        let (writer, events) = (writer.clone(), events.clone());
        let spawned = thread::Builder::new()
            .name("external-source-read".into())
            .spawn(move || read_connection(reading, &writer, &events));
        if let Err(e) = spawned {
            tracing::warn!("external source: no reader thread: {e}");
        }
    }
}

/// Reads one connection until it ends.
fn read_connection(stream: TcpStream, writer: &Writer, events: &Sender<Event>) {
    let mut reader = BufReader::new(stream);
    let mut line_number = 0u64;
    let mut greeted = false;
    let mut buffer = Vec::new();
    loop {
        buffer.clear();
        line_number += 1;
        let read = (&mut reader).take(MAX_LINE_BYTES as u64 + 1).read_until(b'\n', &mut buffer);
        let refused = match read {
            Ok(0) | Err(_) => break,
            Ok(_) if buffer.last() != Some(&b'\n') => {
                let error = if buffer.len() > MAX_LINE_BYTES {
                    ExternalError::LineTooLong { line: line_number, limit: MAX_LINE_BYTES }
                } else {
                    ExternalError::Truncated { bytes: buffer.len() }
                };
                report(writer, events, error);
                break;
            }
            Ok(_) => match decode_line(&buffer, line_number) {
                Ok(message) if !greeted => match check_hello(&message) {
                    Ok(()) => {
                        greeted = true;
                        let _ = events.send(Event::Connected);
                        continue;
                    }
                    Err(e) => {
                        report(writer, events, e);
                        break;
                    }
                },
                Ok(ClientMessage::Hello { .. }) => continue,
                Ok(message) => {
                    let _ = events.send(Event::Result(message));
                    continue;
                }
                Err(e) if !greeted => e,
                Err(e) => {
                    report(writer, events, e);
                    continue;
                }
            },
        };
        // A bad first line: the handshake failed.
        report(writer, events, ExternalError::BadHandshake { detail: refused.to_string() });
        break;
    }
    let _ = reader.get_ref().shutdown(std::net::Shutdown::Both);
    if greeted {
        let _ = events.send(Event::Disconnected);
    }
}

fn report(writer: &Writer, events: &Sender<Event>, error: ExternalError) {
    writer.send(&ServerMessage::Error { kind: error.kind(), detail: error.to_string() });
    let _ = events.send(Event::Error(error));
}
