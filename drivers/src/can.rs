//! CAN devices over SocketCAN: a small [`CanBus`] seam (so the backends are
//! tested without a bus) and the uSkin board as a [`TactileSource`]. The
//! hand is in [`super::can_hand`].

use std::io;
use std::sync::Arc;
use std::time::{Duration, Instant};

use slidetrack_core::{
    Clock, DecoderCounters, DeviceError, ErrorKind, TactileInfo, TactileSample, TactileSource,
};
use socketcan::{CanDataFrame, EmbeddedFrame, ExtendedId, Id, Socket, StandardId};

use crate::can_protocol::{CanFrame, CanScanAssembler};
use crate::config::CanTactileConfig;
use crate::io_error_kind;
use crate::sensors::{pick_board_taxels, tactile_info};

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
}

/// A raw SocketCAN socket bound to one interface.
pub struct SocketCanBus {
    socket: socketcan::CanSocket,
    name: String,
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
        Ok(SocketCanBus { socket, name: interface.to_string() })
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
}

/// A uSkin board on CAN (XELA layout, see `docs/protocols.md`).
pub struct CanTactile {
    bus: Arc<dyn CanBus>,
    device: String,
    assembler: CanScanAssembler,
    board_taxels: Vec<usize>,
    info: TactileInfo,
    clock: Arc<dyn Clock>,
    timeout: Duration,
    startup_timeout: Duration,
    started: bool,
    frames_seen: u64,
    failed: Option<DeviceError>,
}

impl CanTactile {
    /// Opens `cfg.interface` and starts the board.
    pub fn open(cfg: &CanTactileConfig, clock: Arc<dyn Clock>) -> Result<CanTactile, DeviceError> {
        CanTactile::with_bus(Arc::new(SocketCanBus::open(&cfg.interface)?), cfg, clock)
    }

    /// The board on `bus`: sends the start command.
    pub fn with_bus(
        bus: Arc<dyn CanBus>,
        cfg: &CanTactileConfig,
        clock: Arc<dyn Clock>,
    ) -> Result<CanTactile, DeviceError> {
        let layout = cfg.layout();
        let device = bus.name().to_string();
        bus.send(&layout.start_command()).map_err(|e| {
            DeviceError::new(io_error_kind(&e), &device, format!("cannot send the start command: {e}"))
        })?;
        Ok(CanTactile {
            device: device.clone(),
            assembler: CanScanAssembler::new(layout, CanScanAssembler::span_for_rate(cfg.rate_hz)),
            board_taxels: cfg.board_taxels(),
            info: tactile_info(&device, cfg.rate_hz, &cfg.sensors, &cfg.fingers),
            clock,
            timeout: Duration::from_millis(cfg.timeout_ms),
            startup_timeout: Duration::from_millis(cfg.startup_timeout_ms.max(cfg.timeout_ms)),
            started: false,
            frames_seen: 0,
            failed: None,
            bus,
        })
    }

    fn timeout_error(&self, waited: Duration) -> DeviceError {
        let ms = waited.as_millis();
        let l = self.assembler.layout();
        let detail = if self.assembler.counters().frames == 0 {
            format!(
                "no taxel frames (ids 0x{:X}..=0x{:X}) within {ms} ms ({} other frames): is board {} powered \
                 and streaming?",
                l.taxel_base_id,
                l.taxel_base_id + u32::from(l.taxels) - 1,
                self.frames_seen,
                l.board
            )
        } else {
            format!("no complete scan within {ms} ms ({})", self.assembler.counters())
        };
        DeviceError::new(ErrorKind::Timeout, &self.device, detail)
    }
}

impl TactileSource for CanTactile {
    /// # Contract
    /// - Blocks until a scan of the board is complete and its mapped taxels
    ///   are valid; scans with a mapped taxel marked invalid are dropped and
    ///   counted as incomplete. The sample time is the session time at which
    ///   the scan's last frame was received; `sequence` counts the board's
    ///   scans (dropped ones included).
    /// - `Timeout` when no usable scan arrives within `timeout_ms` (the first:
    ///   `startup_timeout_ms`); `Disconnected` when the interface goes away,
    ///   after which every call fails.
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
            let frame = match self.bus.recv(remaining) {
                Ok(Some(f)) => f,
                Ok(None) => continue,
                Err(e) => {
                    let kind = io_error_kind(&e);
                    let err = DeviceError::new(kind, &self.device, format!("receive failed: {e}"));
                    if kind == ErrorKind::Disconnected {
                        self.failed = Some(err.clone());
                    }
                    return Err(err);
                }
            };
            self.frames_seen += 1;
            let Some(scan) = self.assembler.push(self.clock.now(), &frame) else { continue };
            match pick_board_taxels(&scan.taxels, &self.board_taxels) {
                Some(raw) => {
                    self.started = true;
                    return Ok(TactileSample::new(scan.t, scan.sequence, raw));
                }
                None => self.assembler.count_unusable_scan(),
            }
        }
    }

    fn info(&self) -> TactileInfo {
        self.info.clone()
    }

    fn counters(&self) -> Option<DecoderCounters> {
        Some(self.assembler.counters())
    }
}

#[cfg(test)]
mod tests;
