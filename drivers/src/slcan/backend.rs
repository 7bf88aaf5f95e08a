//! An SLCAN adapter on a serial port as a [`CanBus`], without `slcand`: the
//! port's bytes go through a [`SlcanDecoder`]; commands are encoded with
//! [`SlcanCommand`]. The protocol is in `docs/protocols.md` ("SLCAN").

use std::collections::VecDeque;
use std::io::{self, Read, Write};
use std::sync::{Mutex, MutexGuard, PoisonError};
use std::time::{Duration, Instant};

use serialport::{ClearBuffer, FlowControl, SerialPort, TTYPort};
use slidetrack_core::{DeviceError, ErrorKind};

use crate::can::backend::socketcan::{BusEvent, CanBus};
use crate::can::protocol::CanFrame;
use crate::io_error_kind::io_error_kind;
use crate::slcan::protocol::{
    SlcanClock, SlcanCommand, SlcanConfig, SlcanCounters, SlcanDecoder, SlcanEvent,
};

pub mod emulated;
pub mod emulator;

pub use emulator::SlcanEmulator;

/// Bytes read from the port at a time.
const READ_CHUNK: usize = 4096;

/// The adapter's timestamp of a received frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct AdapterTimestamp {
    /// As the adapter sent it: milliseconds modulo 60000.
    pub raw_ms: u16,
    /// Unwrapped by a [`SlcanClock`] with the host's reception times:
    /// milliseconds on the adapter's clock, counted from the start of the
    /// adapter's minute in which the first timestamped frame after
    /// [`SlcanBus::open`] arrived. Never decreases.
    pub adapter_ms: u64,
}

/// A data frame as received, with its times.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SlcanReceived {
    /// The frame.
    pub frame: CanFrame,
    /// The adapter's timestamp, when the adapter sends them (`Z1`).
    pub timestamp: Option<AdapterTimestamp>,
    /// When the host read the bytes that completed the frame.
    pub received_at: Instant,
}

/// What came from the adapter, in order: frames and command replies.
enum Incoming {
    Frame(SlcanReceived),
    /// `true` for OK (`\r`, `z`, `Z`), `false` for BEL.
    Reply(bool),
}

/// The reading half: the port, its decoder and what it decoded.
struct Reader {
    port: TTYPort,
    decoder: SlcanDecoder,
    clock: SlcanClock,
    epoch: Instant,
    incoming: VecDeque<Incoming>,
    buf: Box<[u8]>,
}

impl Reader {
    /// Reads once, waiting at most `timeout`, and decodes what came. Queues
    /// at most one read's worth of frames.
    fn read_once(&mut self, timeout: Duration) -> io::Result<()> {
        self.port.set_timeout(timeout)?;
        match self.port.read(&mut self.buf) {
            Ok(0) => Err(io::Error::new(io::ErrorKind::UnexpectedEof, "the port reached end of file")),
            Ok(n) => {
                self.ingest(n);
                Ok(())
            }
            Err(e) if matches!(e.kind(), io::ErrorKind::Interrupted) => Ok(()),
            Err(e) if io_error_kind(&e) == ErrorKind::Timeout => Ok(()),
            Err(e) => Err(e),
        }
    }

    fn ingest(&mut self, n: usize) {
        let received_at = Instant::now();
        let host_ms = u64::try_from(received_at.duration_since(self.epoch).as_millis()).unwrap_or(u64::MAX);
        let Reader { decoder, clock, incoming, buf, .. } = self;
        decoder.feed(&buf[..n], |event| match event {
            SlcanEvent::Frame { frame, remote: false, timestamp_ms } => {
                let timestamp = timestamp_ms.and_then(|raw_ms| {
                    clock.unwrap_at(raw_ms, host_ms).map(|adapter_ms| AdapterTimestamp { raw_ms, adapter_ms })
                });
                incoming.push_back(Incoming::Frame(SlcanReceived { frame, timestamp, received_at }));
            }
            SlcanEvent::Ok | SlcanEvent::TransmitAck { .. } => incoming.push_back(Incoming::Reply(true)),
            SlcanEvent::Error => incoming.push_back(Incoming::Reply(false)),
            other => tracing::trace!("slcan: {other:?}"),
        });
    }
}

/// A CAN bus behind an SLCAN adapter on a serial port (`/dev/ttyUSB0`).
///
/// # Contract
/// - [`open`](Self::open) sets the adapter up and opens its channel (unless
///   `setup` is false); dropping the bus closes the channel (`C`).
/// - As a [`CanBus`]: `recv` returns the next data frame (remote frames,
///   replies and malformed lines are skipped and counted), `send` writes a
///   `t`/`T` command and does not wait for the adapter's reply (a BEL
///   refusing it is counted in [`counters`](Self::counters)`().errors`).
///   `recv` calls are serialised (one reader at a time); `send` may run
///   beside them.
/// - A vanished port (hang-up, I/O error, end of file) fails with an
///   `io::Error` that the crate's `io_error_kind` maps to `Disconnected`
///   (as [`SerialTactile`](crate::serial::backend::SerialTactile) does), and every
///   later call fails the same way.
/// - The adapter's timestamps, which the `CanBus` trait cannot carry, come
///   with [`recv_timestamped`](Self::recv_timestamped) or, after `recv`,
///   from [`last_timestamp`](Self::last_timestamp).
pub struct SlcanBus {
    path: String,
    reader: Mutex<Reader>,
    writer: Mutex<TTYPort>,
    counters: Mutex<SlcanCounters>,
    last: Mutex<Option<AdapterTimestamp>>,
    failed: Mutex<Option<String>>,
    close_on_drop: bool,
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

impl SlcanBus {
    /// Opens the adapter at `path` (exclusively, raw, at `config.baud`),
    /// discards what the port buffered, then (when `config.setup`) sends
    /// `C`, `Sn`, `Z1`/`Z0` and `O`, each after the adapter answered the
    /// previous one. A refused command (BEL) fails with an error naming the
    /// port and the command; `C` may be refused (the channel was closed) and
    /// so may `Z0`. An unsupported `config.bitrate` fails before any I/O.
    pub fn open(path: &str, config: &SlcanConfig) -> Result<SlcanBus, DeviceError> {
        let commands =
            config.setup_commands().map_err(|e| DeviceError::new(ErrorKind::Other, path, e.to_string()))?;
        let reply_timeout = Duration::from_millis(config.reply_timeout_ms.max(1));
        let flow = if config.hardware_flow_control { FlowControl::Hardware } else { FlowControl::None };
        let port = serialport::new(path, config.baud)
            .flow_control(flow)
            .timeout(reply_timeout)
            .open_native()
            .map_err(|e| open_error(path, &e))?;
        port.clear(ClearBuffer::All).map_err(|e| open_error(path, &e))?;
        let writer = port.try_clone_native().map_err(|e| open_error(path, &e))?;
        let mut bus = SlcanBus {
            path: path.to_string(),
            reader: Mutex::new(Reader {
                port,
                decoder: SlcanDecoder::new(),
                clock: SlcanClock::new(),
                epoch: Instant::now(),
                incoming: VecDeque::new(),
                buf: vec![0; READ_CHUNK].into_boxed_slice(),
            }),
            writer: Mutex::new(writer),
            counters: Mutex::new(SlcanCounters::default()),
            last: Mutex::new(None),
            failed: Mutex::new(None),
            close_on_drop: false,
        };
        if config.setup {
            for (command, bell_tolerated) in commands {
                // From `O` on the channel may be open: close it on drop.
                bus.close_on_drop |= command == SlcanCommand::Open;
                bus.command(command, bell_tolerated, reply_timeout, config.baud)?;
            }
        }
        Ok(bus)
    }

    /// Sends `command` and waits for its reply; frames received meanwhile
    /// precede the reply and are dropped (the channel is not open yet).
    fn command(
        &self,
        command: SlcanCommand,
        bell_tolerated: bool,
        timeout: Duration,
        baud: u32,
    ) -> Result<(), DeviceError> {
        let text = command.text();
        let error = |kind, detail: String| DeviceError::new(kind, &self.path, detail);
        lock(&self.writer)
            .write_all(&command.encode())
            .map_err(|e| error(io_error_kind(&e), format!("cannot send `{text}`: {e}")))?;
        let mut reader = lock(&self.reader);
        let deadline = Instant::now() + timeout;
        loop {
            while let Some(item) = reader.incoming.pop_front() {
                match item {
                    Incoming::Reply(true) => return Ok(()),
                    Incoming::Reply(false) if bell_tolerated => {
                        tracing::debug!("{}: the adapter refused `{text}` (tolerated)", self.path);
                        return Ok(());
                    }
                    Incoming::Reply(false) => return Err(error(ErrorKind::Other, refused(&command))),
                    Incoming::Frame(_) => {}
                }
            }
            let remaining = deadline.saturating_duration_since(Instant::now());
            if remaining.is_zero() {
                let ms = timeout.as_millis();
                let detail = format!(
                    "no reply to `{text}` within {ms} ms: is this an SLCAN adapter, and is the port's speed \
                     ({baud} baud) and flow control right?"
                );
                return Err(error(ErrorKind::Timeout, detail));
            }
            reader.read_once(remaining).map_err(|e| {
                error(io_error_kind(&e), format!("reading the reply to `{text}` failed: {e}"))
            })?;
        }
    }

    /// The next data frame with its timestamps, or `None` after `timeout`.
    pub fn recv_timestamped(&self, timeout: Duration) -> io::Result<Option<SlcanReceived>> {
        let mut reader = lock(&self.reader);
        self.check_failed()?;
        let deadline = Instant::now() + timeout;
        loop {
            while let Some(item) = reader.incoming.pop_front() {
                match item {
                    Incoming::Frame(received) => {
                        *lock(&self.last) = received.timestamp;
                        return Ok(Some(received));
                    }
                    Incoming::Reply(false) => tracing::debug!("{}: the adapter answered BEL", self.path),
                    Incoming::Reply(true) => {}
                }
            }
            let remaining = deadline.saturating_duration_since(Instant::now());
            if remaining.is_zero() {
                return Ok(None);
            }
            let read = reader.read_once(remaining);
            *lock(&self.counters) = reader.decoder.counters();
            read.map_err(|e| self.fail(e))?;
        }
    }

    /// The adapter's timestamp of the frame the last `recv` (or
    /// `recv_timestamped`) returned; `None` when it had none (timestamps
    /// off) or before the first frame. With several threads receiving, use
    /// [`recv_timestamped`](Self::recv_timestamped) instead.
    pub fn last_timestamp(&self) -> Option<AdapterTimestamp> {
        *lock(&self.last)
    }

    /// What the decoder counted (frames, BEL replies, malformed lines, ...),
    /// as of the last read.
    pub fn counters(&self) -> SlcanCounters {
        *lock(&self.counters)
    }

    /// The port's path.
    pub fn path(&self) -> &str {
        &self.path
    }

    fn check_failed(&self) -> io::Result<()> {
        match &*lock(&self.failed) {
            Some(why) => Err(io::Error::new(io::ErrorKind::BrokenPipe, why.clone())),
            None => Ok(()),
        }
    }

    /// Remembers a vanished port, so that every later call fails too.
    fn fail(&self, e: io::Error) -> io::Error {
        if io_error_kind(&e) == ErrorKind::Disconnected {
            lock(&self.failed).get_or_insert_with(|| format!("the adapter is gone: {e}"));
        }
        e
    }
}

impl CanBus for SlcanBus {
    fn send(&self, frame: &CanFrame) -> io::Result<()> {
        self.check_failed()?;
        let bytes = SlcanCommand::Transmit(*frame).encode();
        lock(&self.writer).write_all(&bytes).map_err(|e| self.fail(e))
    }

    fn recv(&self, timeout: Duration) -> io::Result<Option<CanFrame>> {
        Ok(self.recv_timestamped(timeout)?.map(|r| r.frame))
    }

    /// The frame's age counts from when the host read the bytes that
    /// completed it (the adapter's millisecond timestamps are kept in
    /// [`recv_timestamped`](Self::recv_timestamped), not used for the age).
    fn recv_event(&self, timeout: Duration) -> io::Result<Option<BusEvent>> {
        Ok(self
            .recv_timestamped(timeout)?
            .map(|r| BusEvent::Frame { frame: r.frame, age: Some(r.received_at.elapsed()) }))
    }

    fn name(&self) -> &str {
        &self.path
    }
}

impl Drop for SlcanBus {
    fn drop(&mut self) {
        if self.close_on_drop && lock(&self.failed).is_none() {
            let close = SlcanCommand::Close.encode();
            if let Err(e) = lock(&self.writer).write_all(&close) {
                tracing::debug!("{}: cannot close the channel: {e}", self.path);
            }
        }
    }
}

fn refused(command: &SlcanCommand) -> String {
    let hint = match command {
        SlcanCommand::Timestamps(true) => {
            ": the firmware may have no timestamps (CANable's slcan firmware has none); set `timestamps = false`"
        }
        SlcanCommand::Bitrate(_) => ": is the bit rate supported by this adapter?",
        SlcanCommand::Open => ": was the bit rate accepted? is another program using the adapter?",
        _ => "",
    };
    format!("the adapter refused `{}` (BEL){hint}", command.text())
}

fn open_error(path: &str, e: &serialport::Error) -> DeviceError {
    use serialport::ErrorKind as K;
    let (kind, hint) = match e.kind() {
        K::NoDevice => (ErrorKind::Disconnected, " (missing, or opened by another program such as slcand)"),
        K::Io(io::ErrorKind::NotFound) => (ErrorKind::Disconnected, " (no such device)"),
        K::Io(io::ErrorKind::PermissionDenied) => {
            (ErrorKind::Other, " (permission denied: add your user to the `dialout` group)")
        }
        _ => (ErrorKind::Other, ""),
    };
    DeviceError::new(kind, path, format!("cannot open the SLCAN adapter's serial port: {e}{hint}"))
}
