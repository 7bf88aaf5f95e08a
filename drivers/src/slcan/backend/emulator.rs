//! An SLCAN adapter made of a pseudo-terminal: it answers the Lawicel
//! commands as an adapter does (`\r` or BEL) and, while its channel is open,
//! streams the CAN frames a caller-supplied source produces, with
//! timestamps when they are on. It records what the host sends (commands
//! and transmitted frames) and can vanish like an unplugged USB adapter.
//! [`SlcanBus`](crate::slcan::backend::SlcanBus) opens its device side like a
//! real port.

use std::io::{Read, Write};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use serialport::{SerialPort, TTYPort};
use slidetrack_core::{DeviceError, ErrorKind};

use crate::can::protocol::CanFrame;
use crate::slcan::protocol::{BEL, CR, MAX_LINE, TIMESTAMP_PERIOD_MS, encode_frame_line, parse_frame_line};

/// Produces the frames of one period; `None` ends the stream (the adapter
/// then only answers commands).
pub type FrameSource = Box<dyn FnMut() -> Option<Vec<CanFrame>> + Send>;

/// How the emulated adapter acknowledges a frame the host transmits.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TransmitAck {
    /// `z\r` after `t`/`r`, `Z\r` after `T`/`R` (Lawicel CANUSB, EasySYNC).
    Lawicel,
    /// A lone `\r` (CANable's slcan firmware, can-utils' slcanpty).
    CarriageReturn,
}

/// How the emulated adapter behaves.
#[derive(Clone, Debug)]
pub struct SlcanEmulatorConfig {
    /// Time between two calls of the source while the channel is open.
    pub period: Duration,
    /// Whether `Z0`/`Z1` are accepted (CANable's slcan firmware refuses them).
    pub timestamps_supported: bool,
    /// The reply to a transmitted frame.
    pub transmit_ack: TransmitAck,
    /// The timestamp clock's value when the channel opens, ms (0 to 59999),
    /// so that tests can see it wrap soon. (Whether real adapters restart
    /// their clock at `O` is not documented; this one does.)
    pub clock_start_ms: u16,
    /// The channel is already open (at 1 Mbit/s), as an adapter that a
    /// previous program left open.
    pub open_at_start: bool,
    /// Unplug by itself this long after it first streamed frames.
    pub unplug_after: Option<Duration>,
}

impl Default for SlcanEmulatorConfig {
    fn default() -> Self {
        SlcanEmulatorConfig {
            period: Duration::from_millis(1),
            timestamps_supported: true,
            transmit_ack: TransmitAck::Lawicel,
            clock_start_ms: 0,
            open_at_start: false,
            unplug_after: None,
        }
    }
}

/// What the emulated adapter saw and did.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct EmulatorRecord {
    /// Every command line received, without its `\r`, in order.
    pub commands: Vec<String>,
    /// The frames the host transmitted (remote frames with zero data).
    pub transmitted: Vec<CanFrame>,
    /// The channel is open.
    pub open: bool,
    /// The last `Sn` code accepted.
    pub bitrate_code: Option<u8>,
    /// Timestamps are on.
    pub timestamps: bool,
    /// Frames streamed to the host.
    pub frames_streamed: u64,
    /// Commands answered with BEL.
    pub refused: u64,
}

struct Shared {
    stop: AtomicBool,
    unplug: AtomicBool,
    record: Mutex<EmulatorRecord>,
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

/// The running emulator; dropping it stops it and closes the terminal.
pub struct SlcanEmulator {
    path: String,
    shared: Arc<Shared>,
    thread: Option<JoinHandle<()>>,
}

impl SlcanEmulator {
    /// Creates the pseudo-terminal and starts answering on a thread named
    /// `slcan-emulator`; the device path is [`path`](Self::path).
    pub fn start(source: FrameSource, config: SlcanEmulatorConfig) -> Result<SlcanEmulator, DeviceError> {
        let error = |detail: String| DeviceError::new(ErrorKind::Other, "slcan emulator", detail);
        let (master, slave) =
            TTYPort::pair().map_err(|e| error(format!("cannot create a pseudo-terminal: {e}")))?;
        let path = slave.name().ok_or_else(|| error("the pseudo-terminal has no device path".into()))?;
        let record = EmulatorRecord {
            open: config.open_at_start,
            bitrate_code: config.open_at_start.then_some(8),
            ..EmulatorRecord::default()
        };
        let shared = Arc::new(Shared {
            stop: AtomicBool::new(false),
            unplug: AtomicBool::new(false),
            record: Mutex::new(record),
        });
        let worker = Worker {
            master,
            _slave: slave,
            source: Some(source),
            config,
            shared: Arc::clone(&shared),
            line: Vec::with_capacity(MAX_LINE),
            overlong: false,
            opened_at: Instant::now(),
            first_frames: None,
        };
        let thread = std::thread::Builder::new()
            .name("slcan-emulator".into())
            .spawn(move || worker.run())
            .map_err(|e| error(format!("cannot start the emulator: {e}")))?;
        Ok(SlcanEmulator { path, shared, thread: Some(thread) })
    }

    /// The device side's path (`/dev/pts/N`), to open as the adapter's port.
    pub fn path(&self) -> &str {
        &self.path
    }

    /// What the adapter saw and did so far.
    pub fn record(&self) -> EmulatorRecord {
        lock(&self.shared.record).clone()
    }

    /// The frames the host transmitted so far.
    pub fn transmitted(&self) -> Vec<CanFrame> {
        lock(&self.shared.record).transmitted.clone()
    }

    /// Unplugs the adapter: the terminal closes, the host sees a hang-up.
    pub fn unplug(&self) {
        self.shared.unplug.store(true, Ordering::SeqCst);
    }
}

impl Drop for SlcanEmulator {
    fn drop(&mut self) {
        self.shared.stop.store(true, Ordering::SeqCst);
        if let Some(t) = self.thread.take()
            && t.join().is_err()
        {
            tracing::warn!("{}: the SLCAN emulator thread panicked", self.path);
        }
    }
}

struct Worker {
    master: TTYPort,
    /// Held so that the master never sees a hang-up while the host reopens.
    _slave: TTYPort,
    source: Option<FrameSource>,
    config: SlcanEmulatorConfig,
    shared: Arc<Shared>,
    line: Vec<u8>,
    overlong: bool,
    /// When the channel last opened: the timestamps count from there.
    opened_at: Instant,
    /// When frames were first streamed.
    first_frames: Option<Instant>,
}

/// Longest wait for a command before looking at the stop flags again.
const POLL: Duration = Duration::from_millis(5);
/// Longest wait for the host to take bytes.
const WRITE_TIMEOUT: Duration = Duration::from_millis(200);

impl Worker {
    fn run(mut self) {
        let mut buf = [0u8; 1024];
        let mut next_batch = Instant::now();
        while !self.shared.stop.load(Ordering::SeqCst) {
            let due = self
                .first_frames
                .zip(self.config.unplug_after)
                .is_some_and(|(t, after)| t.elapsed() >= after);
            if due || self.shared.unplug.load(Ordering::SeqCst) {
                tracing::info!("slcan emulator: unplugging");
                return; // dropping the pseudo-terminal hangs up the device side
            }
            let wait = next_batch.saturating_duration_since(Instant::now()).min(POLL);
            let read = self
                .master
                .set_timeout(wait)
                .map_err(std::io::Error::from)
                .and_then(|()| self.master.read(&mut buf));
            let ok = match read {
                Ok(n) => self.on_bytes(&buf[..n]),
                Err(e)
                    if matches!(e.kind(), std::io::ErrorKind::TimedOut | std::io::ErrorKind::WouldBlock) =>
                {
                    true
                }
                Err(e) => {
                    tracing::warn!("slcan emulator: reading commands failed: {e}");
                    false
                }
            };
            let now = Instant::now();
            if ok && now >= next_batch {
                next_batch += self.config.period;
                if next_batch < now {
                    next_batch = now + self.config.period; // late by a period or more: skip ahead
                }
                if !self.stream_batch() {
                    return;
                }
            }
            if !ok {
                return;
            }
        }
    }

    /// Handles command bytes; false when the host can no longer be written to.
    fn on_bytes(&mut self, bytes: &[u8]) -> bool {
        let mut replies = Vec::new();
        for &b in bytes {
            if b != CR {
                if self.line.len() < MAX_LINE {
                    self.line.push(b);
                } else {
                    self.overlong = true;
                }
                continue;
            }
            let line = std::mem::take(&mut self.line);
            if std::mem::take(&mut self.overlong) {
                lock(&self.shared.record).refused += 1;
                replies.push(BEL);
            } else {
                self.answer(&line, &mut replies);
            }
            self.line = line;
            self.line.clear();
        }
        replies.is_empty() || self.write(&replies)
    }

    /// Appends the reply to one command line (`\r` excluded) to `out`.
    fn answer(&mut self, line: &[u8], out: &mut Vec<u8>) {
        if line.is_empty() {
            return; // a lone CR, as hosts send to flush: no reply
        }
        let mut r = lock(&self.shared.record);
        r.commands.push(line.escape_ascii().to_string());
        let accepted = match line {
            b"O" if !r.open && r.bitrate_code.is_some() => {
                r.open = true;
                self.opened_at = Instant::now();
                true
            }
            b"C" if r.open => {
                r.open = false;
                true
            }
            [b'S', code @ b'0'..=b'8'] if !r.open => {
                r.bitrate_code = Some(code - b'0');
                true
            }
            [b'Z', on @ (b'0' | b'1')] if self.config.timestamps_supported => {
                r.timestamps = *on == b'1';
                true
            }
            b"V" | b"N" | b"F" => {
                let reply: &[u8] = match line[0] {
                    b'V' => b"V0101",
                    b'N' => b"N0001",
                    _ => b"F00",
                };
                out.extend_from_slice(reply);
                true
            }
            [b't' | b'T' | b'r' | b'R', ..] if r.open => match parse_frame_line(line) {
                Ok((frame, _, None)) => {
                    r.transmitted.push(frame);
                    if self.config.transmit_ack == TransmitAck::Lawicel {
                        out.push(if frame.extended { b'Z' } else { b'z' });
                    }
                    true
                }
                _ => false,
            },
            _ => false,
        };
        if accepted {
            out.push(CR);
        } else {
            r.refused += 1;
            out.push(BEL);
        }
    }

    /// Streams one period's frames when the channel is open; false when the
    /// host can no longer be written to.
    fn stream_batch(&mut self) -> bool {
        let (open, timestamps) = {
            let r = lock(&self.shared.record);
            (r.open, r.timestamps)
        };
        let Some(source) = self.source.as_mut().filter(|_| open) else { return true };
        let Some(frames) = source() else {
            self.source = None;
            return true;
        };
        let elapsed = u64::try_from(self.opened_at.elapsed().as_millis()).unwrap_or(0);
        let period = u64::from(TIMESTAMP_PERIOD_MS);
        let now_ms = ((u64::from(self.config.clock_start_ms) + elapsed) % period) as u16;
        let mut bytes = Vec::with_capacity(frames.len() * 32);
        for frame in &frames {
            encode_frame_line(frame, false, timestamps.then_some(now_ms), &mut bytes);
        }
        lock(&self.shared.record).frames_streamed += frames.len() as u64;
        if !frames.is_empty() {
            self.first_frames.get_or_insert_with(Instant::now);
        }
        self.write(&bytes)
    }

    /// Writes to the host; a host that does not read loses the bytes (as an
    /// adapter's full buffer would); false when the terminal is gone.
    fn write(&mut self, bytes: &[u8]) -> bool {
        if let Err(e) = self.master.set_timeout(WRITE_TIMEOUT) {
            tracing::warn!("slcan emulator: {e}");
        }
        match self.master.write_all(bytes) {
            Ok(()) => true,
            Err(e) if e.kind() == std::io::ErrorKind::TimedOut => {
                tracing::debug!("slcan emulator: the host is not reading; bytes dropped");
                true
            }
            Err(e) => {
                if !self.shared.stop.load(Ordering::SeqCst) {
                    tracing::warn!("slcan emulator: writing failed: {e}");
                }
                false
            }
        }
    }
}

#[cfg(test)]
mod tests;
