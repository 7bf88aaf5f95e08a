//! Tactile boards on CAN in any configured layout (`crate::can::layout`) as a
//! [`TactileSource`], on any [`CanBus`]: SocketCAN or an SLCAN adapter.

use std::sync::Arc;
use std::time::{Duration, Instant};

use slidetrack_core::{
    Clock, DecoderCounters, DeviceError, ErrorKind, TactileInfo, TactileSample, TactileSource,
};

use crate::can::backend::socketcan::bus_errors::BusProblem;
use crate::can::config::CanTactileConfig;
use crate::can::layout::CanLayoutDecoder;
use crate::io_error_kind::io_error_kind;
use crate::sensors::tactile_info;

pub mod socketcan;

pub use socketcan::{BusEvent, CanBus, SocketCanBus};

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
    /// [`crate::slcan::backend::emulated::EmulatedSlcanTactile`]'s.)
    pub fn open(cfg: &CanTactileConfig, clock: Arc<dyn Clock>) -> Result<CanTactile, DeviceError> {
        let bus: Arc<dyn CanBus> = match &cfg.slcan {
            Some(s) => Arc::new(crate::slcan::backend::SlcanBus::open(&s.port, &s.adapter())?),
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
            info: tactile_info(&device, rate_hz, &cfg.sensors, cfg.fingers.as_ref()),
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
                return Ok(TactileSample::new(scan.t, scan.sequence, scan.taxels));
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
