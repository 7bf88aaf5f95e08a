//! CAN devices: a small [`CanBus`] seam (SocketCAN here, an SLCAN adapter in
//! [`crate::slcan_bus`], memory in tests) and the tactile boards in any
//! configured layout as a [`TactileSource`]. The hand is in
//! [`super::can_hand`].
//!
//! SocketCAN sockets ask the kernel for error frames (bus-off,
//! error-passive, missing ACK, protocol errors: [`bus_errors::ERROR_MASK`])
//! and for receive timestamps (`SO_TIMESTAMPNS`, the kernel's
//! `CLOCK_REALTIME` when the frame arrived). A timestamp is mapped onto the
//! session clock by its age: `t = clock.now() - (SystemTime::now() -
//! timestamp)`, read right after the frame, so that the time a frame waited
//! in the socket's queue is not counted; the wall clock's steps between the
//! two readings are microseconds apart and cancel out.

use std::io;
use std::sync::Arc;
use std::time::{Duration, Instant, SystemTime};

use slidetrack_core::{
    Clock, DecoderCounters, DeviceError, ErrorKind, TactileInfo, TactileSample, TactileSource,
};
use socketcan::{CanDataFrame, EmbeddedFrame, ExtendedId, Id, Socket, SocketOptions, StandardId};

use crate::can_layout::CanLayoutDecoder;
use crate::can_protocol::CanFrame;
use crate::config::CanTactileConfig;
use crate::io_error_kind;
use crate::sensors::tactile_info;

pub mod bus_errors;

use bus_errors::BusProblem;

/// What a bus delivered.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BusEvent {
    /// A data frame.
    Frame {
        /// The frame.
        frame: CanFrame,
        /// How long ago the kernel (or the host's reader) received it, when
        /// known; `None`: just now.
        age: Option<Duration>,
    },
    /// An error frame's problem.
    Problem(BusProblem),
}

/// Moves CAN frames; the backends hold one.
///
/// # Contract
/// - `send` queues one frame or fails (`io::ErrorKind` of the socket).
/// - `recv` returns the next frame, `Ok(None)` after `timeout` without one.
///   Remote and error frames are skipped.
/// - Both may be called from several threads at once.
pub trait CanBus: Send + Sync {
    /// Sends one frame.
    fn send(&self, frame: &CanFrame) -> io::Result<()>;
    /// The next data frame, or `None` after `timeout`.
    fn recv(&self, timeout: Duration) -> io::Result<Option<CanFrame>>;
    /// The interface name, for messages.
    fn name(&self) -> &str;
    /// The next data frame with its age, or a bus problem; `None` after
    /// `timeout`. By default: [`recv`](Self::recv), no age, no problems.
    fn recv_event(&self, timeout: Duration) -> io::Result<Option<BusEvent>> {
        Ok(self.recv(timeout)?.map(|frame| BusEvent::Frame { frame, age: None }))
    }
}

/// A raw SocketCAN socket bound to one interface.
pub struct SocketCanBus {
    socket: socketcan::CanSocket,
    name: String,
    /// `SO_TIMESTAMPNS` is on.
    timestamps: bool,
}

impl SocketCanBus {
    /// Opens `interface` (`can0`, `vcan0`).
    pub fn open(interface: &str) -> Result<SocketCanBus, DeviceError> {
        let socket = socketcan::CanSocket::open(interface).map_err(|e| {
            let kind = match io_error_kind(&e) {
                ErrorKind::Other => ErrorKind::Disconnected,
                k => k,
            };
            DeviceError::new(
                kind,
                interface,
                format!("cannot open CAN interface: {e} (is it up? `ip link show {interface}`)"),
            )
        })?;
        Ok(SocketCanBus { socket, name: interface.to_string(), timestamps: false })
    }

    /// Opens `interface` for a tactile source: error frames of
    /// [`bus_errors::ERROR_MASK`] and kernel receive timestamps on.
    pub fn open_for_tactile(interface: &str) -> Result<SocketCanBus, DeviceError> {
        let mut bus = SocketCanBus::open(interface)?;
        bus.socket.set_error_filter(bus_errors::ERROR_MASK).map_err(|e| {
            DeviceError::new(io_error_kind(&e), interface, format!("cannot set the CAN error filter: {e}"))
        })?;
        match bus.socket.set_recv_timestamp(true) {
            Ok(()) => bus.timestamps = true,
            Err(e) => tracing::debug!("{interface}: no kernel receive timestamps ({e}); stamping on read"),
        }
        Ok(bus)
    }

    /// One frame (data or error) with its kernel timestamp when on.
    fn read_any(&self, timeout: Duration) -> io::Result<(socketcan::CanFrame, Option<SystemTime>)> {
        if self.timestamps {
            self.socket.set_read_timeout(timeout)?;
            let (frame, at) = self.socket.read_frame_with_timestamp()?;
            Ok((frame, Some(at)))
        } else {
            Ok((self.socket.read_frame_timeout(timeout)?, None))
        }
    }
}

fn to_socketcan(frame: &CanFrame) -> io::Result<CanDataFrame> {
    let id: Option<Id> = if frame.extended {
        ExtendedId::new(frame.id).map(Id::Extended)
    } else {
        u16::try_from(frame.id).ok().and_then(StandardId::new).map(Id::Standard)
    };
    id.and_then(|id| CanDataFrame::new(id, frame.data())).ok_or_else(|| {
        io::Error::new(io::ErrorKind::InvalidInput, format!("frame 0x{:X} does not fit CAN", frame.id))
    })
}

impl CanBus for SocketCanBus {
    fn send(&self, frame: &CanFrame) -> io::Result<()> {
        self.socket.write_frame(&to_socketcan(frame)?)
    }

    fn recv(&self, timeout: Duration) -> io::Result<Option<CanFrame>> {
        let deadline = Instant::now() + timeout;
        loop {
            let remaining = deadline.saturating_duration_since(Instant::now());
            if remaining.is_zero() {
                return Ok(None);
            }
            match self.socket.read_frame_timeout(remaining) {
                Ok(socketcan::CanFrame::Data(d)) => {
                    let id = socketcan::Frame::raw_id(&d);
                    if let Some(f) = CanFrame::new(id, d.is_extended(), d.data()) {
                        return Ok(Some(f));
                    }
                }
                Ok(_) => {} // remote and error frames
                Err(e) if matches!(e.kind(), io::ErrorKind::TimedOut | io::ErrorKind::WouldBlock) => {
                    return Ok(None);
                }
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                Err(e) => return Err(e),
            }
        }
    }

    fn name(&self) -> &str {
        &self.name
    }

    fn recv_event(&self, timeout: Duration) -> io::Result<Option<BusEvent>> {
        let deadline = Instant::now() + timeout;
        loop {
            let remaining = deadline.saturating_duration_since(Instant::now());
            if remaining.is_zero() {
                return Ok(None);
            }
            match self.read_any(remaining) {
                Ok((socketcan::CanFrame::Data(d), at)) => {
                    let age = at.map(|at| SystemTime::now().duration_since(at).unwrap_or_default());
                    let id = socketcan::Frame::raw_id(&d);
                    if let Some(frame) = CanFrame::new(id, d.is_extended(), d.data()) {
                        return Ok(Some(BusEvent::Frame { frame, age }));
                    }
                }
                Ok((socketcan::CanFrame::Error(e), _)) => {
                    if let Some(p) = bus_errors::classify(e.error_bits(), e.data()) {
                        return Ok(Some(BusEvent::Problem(p)));
                    }
                }
                Ok(_) => {} // remote frames
                Err(e) if matches!(e.kind(), io::ErrorKind::TimedOut | io::ErrorKind::WouldBlock) => {
                    return Ok(None);
                }
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                Err(e) => return Err(e),
            }
        }
    }
}

/// Taxel frames on CAN in the configured layout (see `docs/protocols.md`),
/// read from any [`CanBus`].
pub struct CanTactile {
    bus: Arc<dyn CanBus>,
    device: String,
    decoder: CanLayoutDecoder,
    info: TactileInfo,
    clock: Arc<dyn Clock>,
    timeout: Duration,
    startup_timeout: Duration,
    /// Longest wait for a frame before polling the latest-mode decoder.
    poll_period: Duration,
    started: bool,
    frames_seen: u64,
    last_problem: Option<BusProblem>,
    problems: u64,
    failed: Option<DeviceError>,
}

impl CanTactile {
    /// Opens the configured transport (SocketCAN interface or SLCAN
    /// adapter) and sends the start frames. (`slcan.port = "emulated"` is
    /// [`crate::EmulatedSlcanTactile`]'s.)
    pub fn open(cfg: &CanTactileConfig, clock: Arc<dyn Clock>) -> Result<CanTactile, DeviceError> {
        let bus: Arc<dyn CanBus> = match &cfg.slcan {
            Some(s) => Arc::new(crate::slcan_bus::SlcanBus::open(&s.port, &s.adapter())?),
            None => Arc::new(SocketCanBus::open_for_tactile(&cfg.interface)?),
        };
        CanTactile::with_bus(bus, cfg, cfg.rate_hz, clock)
    }

    /// The boards on `bus`: resolves the layout and sends the start frames.
    /// `rate_hz` is recorded in the layout.
    pub fn with_bus(
        bus: Arc<dyn CanBus>,
        cfg: &CanTactileConfig,
        rate_hz: f64,
        clock: Arc<dyn Clock>,
    ) -> Result<CanTactile, DeviceError> {
        let device = bus.name().to_string();
        let layout = cfg.layout().map_err(|e| DeviceError::new(ErrorKind::Other, &device, e.to_string()))?;
        for (frame, key) in &layout.start {
            bus.send(frame).map_err(|e| {
                DeviceError::new(
                    io_error_kind(&e),
                    &device,
                    format!("cannot send the start frame ({key}): {e}"),
                )
            })?;
        }
        let poll_period =
            Duration::from_secs_f64(0.25 / cfg.rate_hz.max(1.0)).max(Duration::from_micros(200));
        Ok(CanTactile {
            device: device.clone(),
            decoder: CanLayoutDecoder::new(layout, cfg.rate_hz),
            info: tactile_info(&device, rate_hz, &cfg.sensors, &cfg.fingers),
            clock,
            timeout: Duration::from_millis(cfg.timeout_ms),
            startup_timeout: Duration::from_millis(cfg.startup_timeout_ms.max(cfg.timeout_ms)),
            poll_period,
            started: false,
            frames_seen: 0,
            last_problem: None,
            problems: 0,
            failed: None,
            bus,
        })
    }

    fn timeout_error(&self, waited: Duration) -> DeviceError {
        let ms = waited.as_millis();
        let slots = &self.decoder.layout().slots;
        let mut detail = if self.decoder.counters().frames == 0 {
            let first = slots.first().map_or(0, |((id, _), _)| *id);
            format!(
                "no taxel frames (first id 0x{first:X}, {} ids) within {ms} ms ({} other frames): is the board \
                 powered and streaming, and is the layout right?",
                slots.len(),
                self.frames_seen
            )
        } else {
            format!("no complete scan within {ms} ms ({})", self.decoder.counters())
        };
        if let Some(p) = self.last_problem {
            detail.push_str(&format!("; last of {} bus problems: {p}", self.problems));
        }
        DeviceError::new(ErrorKind::Timeout, &self.device, detail)
    }

    fn fail(&mut self, kind: ErrorKind, detail: String) -> DeviceError {
        let err = DeviceError::new(kind, &self.device, detail);
        if kind == ErrorKind::Disconnected {
            self.failed = Some(err.clone());
        }
        err
    }
}

impl TactileSource for CanTactile {
    /// # Contract
    /// - Blocks until the decoder emits a scan (complete mode: every mapped
    ///   taxel arrived valid; latest mode: due at `rate_hz`). The sample
    ///   time is the session time at which the scan's last frame was
    ///   received (kernel timestamp where the bus has one); `sequence` is
    ///   the decoder's.
    /// - `Timeout` when no scan arrives within `timeout_ms` (the first:
    ///   `startup_timeout_ms`), naming the last bus problem seen (no ACK,
    ///   error-passive); `Disconnected` when the interface goes away or the
    ///   controller goes bus-off, after which every call fails.
    fn read(&mut self) -> Result<TactileSample, DeviceError> {
        if let Some(e) = &self.failed {
            return Err(e.clone());
        }
        let limit = if self.started { self.timeout } else { self.startup_timeout };
        let deadline = Instant::now() + limit;
        loop {
            let remaining = deadline.saturating_duration_since(Instant::now());
            if remaining.is_zero() {
                return Err(self.timeout_error(limit));
            }
            let scan = match self.bus.recv_event(remaining.min(self.poll_period)) {
                Ok(Some(BusEvent::Frame { frame, age })) => {
                    self.frames_seen += 1;
                    let now = self.clock.now();
                    let t =
                        slidetrack_core::TimeNs(now.0.saturating_sub(age.map_or(0, |a| a.as_nanos() as u64)));
                    self.decoder.push(t, &frame)
                }
                Ok(Some(BusEvent::Problem(p))) => {
                    self.problems += 1;
                    if p.is_fatal() {
                        return Err(self.fail(ErrorKind::Disconnected, p.to_string()));
                    }
                    if self.last_problem != Some(p) {
                        tracing::warn!("{}: {p}", self.device);
                    }
                    self.last_problem = Some(p);
                    continue;
                }
                Ok(None) => self.decoder.poll(self.clock.now()),
                Err(e) => return Err(self.fail(io_error_kind(&e), format!("receive failed: {e}"))),
            };
            if let Some(scan) = scan {
                self.started = true;
                return Ok(TactileSample { t: scan.t, sequence: scan.sequence, raw: scan.taxels });
            }
        }
    }

    fn info(&self) -> TactileInfo {
        self.info.clone()
    }

    fn counters(&self) -> Option<DecoderCounters> {
        Some(self.decoder.counters())
    }
}

impl Drop for CanTactile {
    /// Sends the stop frames, if any (best effort: the bus may be gone).
    fn drop(&mut self) {
        if self.failed.is_some() {
            return;
        }
        for (frame, key) in &self.decoder.layout().stop {
            if let Err(e) = self.bus.send(frame) {
                tracing::debug!("{}: cannot send the stop frame ({key}): {e}", self.device);
            }
        }
    }
}

#[cfg(test)]
mod tests;
