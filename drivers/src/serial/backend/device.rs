//! [`SerialTactile`]: tactile modules streaming the serial format from a
//! real port (or an emulator's pseudo-terminal).

use std::collections::VecDeque;
use std::io::Read;
use std::sync::Arc;
use std::time::{Duration, Instant};

use serialport::{ClearBuffer, SerialPort, TTYPort};
use slidetrack_core::{
    Clock, DecoderCounters, DeviceError, ErrorKind, TactileInfo, TactileSample, TactileSource,
};

use crate::io_error_kind::io_error_kind;
use crate::sensors::{module_taxels, tactile_info};
use crate::serial::config::SerialTactileConfig;
use crate::serial::protocol::{SerialDecoder, SerialEvent};
use crate::serial::scan::{ModuleScanAssembler, SequenceUnwrapper};

/// Bytes read from the port at a time.
const READ_CHUNK: usize = 4096;

/// Tactile modules streaming the serial format (see `docs/protocols.md`).
pub struct SerialTactile {
    port: TTYPort,
    device: String,
    info: TactileInfo,
    decoder: SerialDecoder,
    assembler: ModuleScanAssembler,
    unwrapper: SequenceUnwrapper,
    clock: Arc<dyn Clock>,
    timeout: Duration,
    startup_timeout: Duration,
    started: bool,
    bytes_received: u64,
    ready: VecDeque<TactileSample>,
    buf: Box<[u8]>,
    failed: Option<DeviceError>,
}

impl SerialTactile {
    /// Opens `path` (exclusively, raw mode, at `cfg.baud`) and discards
    /// whatever the port buffered before; sample times are taken on `clock`.
    pub fn open(
        path: &str,
        cfg: &SerialTactileConfig,
        rate_hz: f64,
        clock: Arc<dyn Clock>,
    ) -> Result<SerialTactile, DeviceError> {
        let port = serialport::new(path, cfg.baud)
            .timeout(Duration::from_millis(cfg.timeout_ms))
            .open_native()
            .map_err(|e| open_error(path, &e))?;
        port.clear(ClearBuffer::Input).map_err(|e| open_error(path, &e))?;
        Ok(SerialTactile {
            port,
            device: path.to_string(),
            info: tactile_info(path, rate_hz, &cfg.sensors, cfg.fingers.as_ref()),
            decoder: SerialDecoder::new(),
            assembler: ModuleScanAssembler::new(&module_taxels(&cfg.sensors)),
            unwrapper: SequenceUnwrapper::default(),
            clock,
            timeout: Duration::from_millis(cfg.timeout_ms),
            startup_timeout: Duration::from_millis(cfg.startup_timeout_ms.max(cfg.timeout_ms)),
            started: false,
            bytes_received: 0,
            ready: VecDeque::new(),
            buf: vec![0; READ_CHUNK].into_boxed_slice(),
            failed: None,
        })
    }

    fn fail(&mut self, kind: ErrorKind, detail: String) -> DeviceError {
        let e = DeviceError::new(kind, &self.device, detail);
        if kind == ErrorKind::Disconnected {
            self.failed = Some(e.clone());
        }
        e
    }

    fn timeout_error(&self, waited: Duration) -> DeviceError {
        let waited_ms = waited.as_millis();
        let why = if self.bytes_received == 0 {
            format!("no data within {waited_ms} ms: is the sensor powered and streaming?")
        } else if let Some((module, taxel, have)) = self.assembler.short_module() {
            format!(
                "no complete scan within {waited_ms} ms: a sensor reads {taxel} taxels of module {module}, \
                 whose frames carry {have}"
            )
        } else {
            format!("no complete scan within {waited_ms} ms ({})", self.counters_now())
        };
        DeviceError::new(ErrorKind::Timeout, &self.device, why)
    }

    fn counters_now(&self) -> DecoderCounters {
        DecoderCounters { incomplete_scans: self.assembler.incomplete_scans(), ..self.decoder.counters() }
    }

    /// Decodes `n` bytes of the read buffer received at the current time.
    fn ingest(&mut self, n: usize) {
        let t = self.clock.now();
        self.bytes_received += n as u64;
        let SerialTactile { decoder, assembler, unwrapper, ready, buf, device, .. } = self;
        decoder.feed(&buf[..n], |event| match event {
            SerialEvent::Frame(frame) => {
                if let Some((sequence, raw)) = assembler.push(&frame) {
                    ready.push_back(TactileSample::new(t, unwrapper.unwrap(sequence), raw));
                }
            }
            other => tracing::debug!("{device}: {other:?}"),
        });
    }
}

fn open_error(path: &str, e: &serialport::Error) -> DeviceError {
    use serialport::ErrorKind as K;
    let (kind, hint) = match e.kind() {
        K::NoDevice => (ErrorKind::Disconnected, " (missing, or opened by another program)"),
        K::Io(std::io::ErrorKind::NotFound) => (ErrorKind::Disconnected, " (no such device)"),
        K::Io(std::io::ErrorKind::PermissionDenied) => {
            (ErrorKind::Other, " (permission denied: add your user to the `dialout` group)")
        }
        _ => (ErrorKind::Other, ""),
    };
    DeviceError::new(kind, path, format!("cannot open serial port: {e}{hint}"))
}

impl TactileSource for SerialTactile {
    /// # Contract
    /// - Blocks until the frames of every mapped module of one scan have
    ///   arrived, then returns the scan; several scans decoded from one read
    ///   are returned one per call. The sample time is the session time when
    ///   the bytes that completed the scan were read (the device has no clock
    ///   of its own); `sequence` is the board's scan counter, unwrapped.
    /// - `Timeout` when no scan completes within `timeout_ms` (the first scan:
    ///   `startup_timeout_ms`); `Disconnected` when the port reports a hang-up
    ///   or an I/O error (device unplugged), after which every call fails.
    fn read(&mut self) -> Result<TactileSample, DeviceError> {
        if let Some(e) = &self.failed {
            return Err(e.clone());
        }
        if let Some(sample) = self.ready.pop_front() {
            return Ok(sample);
        }
        let limit = if self.started { self.timeout } else { self.startup_timeout };
        let deadline = Instant::now() + limit;
        loop {
            let remaining = deadline.saturating_duration_since(Instant::now());
            if remaining.is_zero() {
                return Err(self.timeout_error(limit));
            }
            if let Err(e) = self.port.set_timeout(remaining) {
                return Err(self.fail(ErrorKind::Other, format!("cannot set the read timeout: {e}")));
            }
            match self.port.read(&mut self.buf) {
                Ok(0) => {
                    return Err(self.fail(ErrorKind::Disconnected, "the port reached end of file".into()));
                }
                Ok(n) => {
                    self.ingest(n);
                    if let Some(sample) = self.ready.pop_front() {
                        self.started = true;
                        return Ok(sample);
                    }
                }
                Err(e) => match io_error_kind(&e) {
                    ErrorKind::Timeout => {}
                    _ if e.kind() == std::io::ErrorKind::Interrupted => {}
                    kind => {
                        let detail = format!("read failed: {e} (device unplugged?)");
                        return Err(self.fail(kind, detail));
                    }
                },
            }
        }
    }

    fn info(&self) -> TactileInfo {
        self.info.clone()
    }

    fn counters(&self) -> Option<DecoderCounters> {
        Some(self.counters_now())
    }
}
