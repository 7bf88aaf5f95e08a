//! One Modbus RTU transaction at a time on a serial port: write a request,
//! read its response up to the length the request implies, and check it.
//! A corrupted, short, foreign or refused response is an error and is
//! counted; it never reaches the caller as data.

use std::io::{Read, Write};
use std::time::{Duration, Instant};

use serialport::{ClearBuffer, SerialPort, TTYPort};
use slidetrack_core::{DeviceError, ErrorKind};

use crate::io_error_kind::io_error_kind;
use crate::robotiq::modbus::{FrameError, MAX_FRAME, Request, Response, response_len};

/// What the link has seen, for the log and the tests.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LinkCounters {
    /// Requests sent.
    pub transactions: u64,
    /// Valid responses.
    pub ok: u64,
    /// Responses with a bad CRC.
    pub bad_crc: u64,
    /// Responses shorter than their function implies, or of a wrong length.
    pub bad_length: u64,
    /// Responses from another device id.
    pub wrong_device: u64,
    /// Responses of another function, or a write echo that differs.
    pub mismatched: u64,
    /// Exception responses.
    pub exceptions: u64,
    /// Requests without any response in time.
    pub timeouts: u64,
}

impl LinkCounters {
    /// Responses that were received and rejected.
    pub fn rejected(&self) -> u64 {
        self.bad_crc + self.bad_length + self.wrong_device + self.mismatched + self.exceptions
    }

    fn count(&mut self, e: &FrameError) {
        match e {
            FrameError::BadCrc { .. } => self.bad_crc += 1,
            FrameError::Short { .. } | FrameError::BadLength { .. } => self.bad_length += 1,
            FrameError::WrongDevice { .. } => self.wrong_device += 1,
            FrameError::WrongFunction { .. }
            | FrameError::BadEcho { .. }
            | FrameError::UnknownFunction { .. } => {
                self.mismatched += 1;
            }
        }
    }
}

/// A Modbus RTU client on a serial port, talking to one device id.
pub struct RtuLink {
    port: TTYPort,
    device: String,
    device_id: u8,
    response_timeout: Duration,
    counters: LinkCounters,
    buf: Vec<u8>,
}

impl RtuLink {
    /// Opens `path` (exclusively, raw, 8N1 at `baud`) for device `device_id`.
    pub fn open(
        path: &str,
        baud: u32,
        device_id: u8,
        response_timeout: Duration,
    ) -> Result<RtuLink, DeviceError> {
        let port = serialport::new(path, baud)
            .data_bits(serialport::DataBits::Eight)
            .parity(serialport::Parity::None)
            .stop_bits(serialport::StopBits::One)
            .flow_control(serialport::FlowControl::None)
            .timeout(response_timeout)
            .open_native()
            .map_err(|e| {
                let kind = match e.kind() {
                    serialport::ErrorKind::NoDevice => ErrorKind::Disconnected,
                    serialport::ErrorKind::Io(k) => io_error_kind(&std::io::Error::from(k)),
                    _ => ErrorKind::Other,
                };
                DeviceError::new(kind, path, format!("cannot open the gripper's port: {e}"))
            })?;
        port.clear(ClearBuffer::All)
            .map_err(|e| DeviceError::new(ErrorKind::Other, path, format!("cannot clear the port: {e}")))?;
        Ok(RtuLink {
            port,
            device: path.to_string(),
            device_id,
            response_timeout,
            counters: LinkCounters::default(),
            buf: Vec::with_capacity(MAX_FRAME),
        })
    }

    /// The port's path.
    pub fn device(&self) -> &str {
        &self.device
    }

    /// The counters so far.
    pub fn counters(&self) -> LinkCounters {
        self.counters
    }

    /// Sends `request` and returns its checked response. Errors:
    /// `Disconnected` when the port is gone, `Timeout` when nothing came
    /// back, `Corrupt` for a response that is not a valid answer (bad CRC,
    /// short, another device, another function), `Other` for an exception
    /// response.
    pub fn transact(&mut self, request: &Request) -> Result<Response, DeviceError> {
        self.counters.transactions += 1;
        let frame = request.encode(self.device_id);
        self.port
            .write_all(&frame)
            .and_then(|()| self.port.flush())
            .map_err(|e| self.io_error(&e, "write"))?;
        self.read_response(request)?;
        match Response::decode(&self.buf, self.device_id, request) {
            Ok(Response::Exception { function, code }) => {
                self.counters.exceptions += 1;
                Err(self.error(
                    ErrorKind::Other,
                    format!("the gripper refused function {function:#04x} with exception code {code:#04x}"),
                ))
            }
            Ok(response) => {
                self.counters.ok += 1;
                Ok(response)
            }
            Err(e) => {
                self.counters.count(&e);
                self.resynchronise();
                Err(self.error(ErrorKind::Corrupt, format!("rejected response: {e}")))
            }
        }
    }

    /// Reads into `buf` until the response's length, or the timeout.
    fn read_response(&mut self, request: &Request) -> Result<(), DeviceError> {
        self.buf.clear();
        let deadline = Instant::now() + self.response_timeout;
        let mut chunk = [0u8; MAX_FRAME];
        loop {
            let want = response_len(&self.buf, request).unwrap_or(MAX_FRAME);
            if self.buf.len() >= want {
                self.buf.truncate(want);
                return Ok(());
            }
            let remaining = deadline.saturating_duration_since(Instant::now());
            if remaining.is_zero() {
                return self.timed_out();
            }
            self.port.set_timeout(remaining).map_err(|e| self.error(ErrorKind::Other, e.to_string()))?;
            match self.port.read(&mut chunk[..want - self.buf.len()]) {
                Ok(0) => return Err(self.error(ErrorKind::Disconnected, "the port hung up".into())),
                Ok(n) => self.buf.extend_from_slice(&chunk[..n]),
                Err(e)
                    if matches!(e.kind(), std::io::ErrorKind::TimedOut | std::io::ErrorKind::WouldBlock) =>
                {
                    return self.timed_out();
                }
                Err(e) => return Err(self.io_error(&e, "read")),
            }
        }
    }

    fn timed_out(&mut self) -> Result<(), DeviceError> {
        self.resynchronise();
        if self.buf.is_empty() {
            self.counters.timeouts += 1;
            let ms = self.response_timeout.as_millis();
            return Err(self.error(ErrorKind::Timeout, format!("no response within {ms} ms")));
        }
        self.counters.bad_length += 1;
        let detail = format!("short response: {} bytes, then silence", self.buf.len());
        Err(self.error(ErrorKind::Corrupt, detail))
    }

    /// After a rejected response: waits for the line to fall silent, then
    /// drops whatever arrived, so that the next response starts clean.
    fn resynchronise(&mut self) {
        let mut chunk = [0u8; MAX_FRAME];
        let _ = self.port.set_timeout(Duration::from_millis(5));
        for _ in 0..16 {
            match self.port.read(&mut chunk) {
                Ok(n) if n > 0 => {}
                _ => break,
            }
        }
        let _ = self.port.clear(ClearBuffer::Input);
    }

    fn io_error(&self, e: &std::io::Error, what: &str) -> DeviceError {
        self.error(io_error_kind(e), format!("{what} failed: {e}"))
    }

    fn error(&self, kind: ErrorKind, detail: String) -> DeviceError {
        DeviceError::new(kind, &self.device, detail)
    }
}
