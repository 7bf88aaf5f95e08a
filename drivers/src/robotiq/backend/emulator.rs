//! A Robotiq gripper made of a pseudo-terminal: it answers Modbus RTU on
//! the terminal's device side as the gripper does (device id, registers,
//! function codes 3, 4, 6, 16, 23; silence on a bad CRC or another device
//! id), paced like a 115200-baud line, with the register state machine of
//! [`GripperServer`] in front of any [`HandActuator`] and [`HandMonitor`].
//! Faults can be injected: a `gFLT` code, a gripper that falls silent, an
//! unplugged adapter.

use std::io::{Read, Write};
use std::sync::atomic::{AtomicBool, AtomicU8, Ordering};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use serialport::{SerialPort, TTYPort};
use slidetrack_core::{DeviceError, ErrorKind, HandActuator, HandMonitor, WallClock};

use crate::robotiq::config::{RobotiqConfig, RobotiqModel};
use crate::robotiq::modbus::{FrameError, MAX_FRAME, Request, Response, request_len};
use crate::robotiq::model::kinematic_gripper;
use crate::robotiq::server::{GripperServer, ServerRecord};

/// How the emulated gripper behaves.
#[derive(Clone, Debug, PartialEq)]
pub struct RobotiqEmulatorOptions {
    /// Its Modbus device id.
    pub device_id: u8,
    /// Time from `rACT = 1` to `gSTA = 3`.
    pub activation: Duration,
    /// Answer a bad function or address with a Modbus exception response.
    /// The Robotiq manual states exception responses as not supported, so
    /// by default such requests get silence.
    pub exceptions: bool,
    /// Delay each response as a line at this baud rate would (8N1: 10 bits
    /// per byte), plus `gap` before and after it; `None`: answer at once.
    pub pace_baud: Option<u32>,
    /// The silence between frames (Modbus over Serial Line recommends
    /// 1.75 ms above 19200 baud).
    pub gap: Duration,
    /// Report `gFLT = code` this long after the activation completed.
    pub fault: Option<(Duration, u8)>,
    /// Stop answering this long after the activation completed.
    pub silent_after: Option<Duration>,
    /// Close the terminal this long after the activation completed.
    pub unplug_after: Option<Duration>,
    /// Flip a bit in every n-th response (0: never), as line noise would.
    pub corrupt_every: u64,
}

impl Default for RobotiqEmulatorOptions {
    fn default() -> Self {
        RobotiqEmulatorOptions {
            device_id: 9,
            activation: Duration::from_millis(1500),
            exceptions: false,
            pace_baud: Some(115_200),
            gap: Duration::from_micros(1750),
            fault: None,
            silent_after: None,
            unplug_after: None,
            corrupt_every: 0,
        }
    }
}

impl RobotiqEmulatorOptions {
    /// The options of a `[hw.hand] kind = "robotiq"` table's `emulator`.
    pub fn from_config(cfg: &RobotiqConfig) -> RobotiqEmulatorOptions {
        let e = &cfg.emulator;
        let secs = |s: f64| Duration::from_secs_f64(s.max(0.0));
        RobotiqEmulatorOptions {
            device_id: cfg.device_id,
            activation: secs(e.activation_s),
            pace_baud: Some(cfg.baud),
            fault: e.fault_code.map(|c| (secs(e.fault_after_s), c)),
            silent_after: e.silent_after_s.map(secs),
            unplug_after: e.unplug_after_s.map(secs),
            ..RobotiqEmulatorOptions::default()
        }
    }
}

/// What the emulator saw and did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct EmulatorRecord {
    /// The gripper's state machine.
    pub server: ServerRecord,
    /// Requests answered.
    pub answered: u64,
    /// Frames ignored: bad CRC, incomplete, another device id, or refused
    /// without exceptions.
    pub ignored: u64,
    /// Exception responses sent.
    pub exceptions: u64,
}

struct Shared {
    stop: AtomicBool,
    unplug: AtomicBool,
    silent: AtomicBool,
    /// A `gFLT` code to report from now on (0: none pending).
    fault: AtomicU8,
    record: Mutex<EmulatorRecord>,
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

/// The running emulator; dropping it stops it and closes the terminal.
pub struct RobotiqEmulator {
    path: String,
    shared: Arc<Shared>,
    thread: Option<JoinHandle<()>>,
}

impl RobotiqEmulator {
    /// Serves a gripper whose fingers are `actuator` (it gets the requests
    /// the registers ask for) and `monitor` (its `HandStatus.gripper` gives
    /// `gPO`, `gOBJ`, `gCU`), on a new pseudo-terminal, from a thread
    /// named `robotiq-emulator`.
    pub fn start(
        actuator: Box<dyn HandActuator>,
        monitor: Box<dyn HandMonitor>,
        options: RobotiqEmulatorOptions,
    ) -> Result<RobotiqEmulator, DeviceError> {
        let error = |detail: String| DeviceError::new(ErrorKind::Other, "robotiq emulator", detail);
        let (master, slave) =
            TTYPort::pair().map_err(|e| error(format!("cannot create a pseudo-terminal: {e}")))?;
        let path = slave.name().ok_or_else(|| error("the pseudo-terminal has no device path".into()))?;
        let shared = Arc::new(Shared {
            stop: AtomicBool::new(false),
            unplug: AtomicBool::new(false),
            silent: AtomicBool::new(false),
            fault: AtomicU8::new(0),
            record: Mutex::new(EmulatorRecord::default()),
        });
        let worker = Worker {
            master,
            _slave: slave,
            server: GripperServer::new(actuator, monitor, options.activation),
            options,
            shared: Arc::clone(&shared),
            buf: Vec::with_capacity(MAX_FRAME),
            last_byte: Instant::now(),
            fault_done: false,
        };
        let thread = std::thread::Builder::new()
            .name("robotiq-emulator".into())
            .spawn(move || worker.run())
            .map_err(|e| error(format!("cannot start the emulator: {e}")))?;
        Ok(RobotiqEmulator { path, shared, thread: Some(thread) })
    }

    /// A gripper of `model` made of the kinematic model on the wall clock,
    /// stopping on an object `object_width_m` wide when there is one.
    pub fn kinematic(
        model: RobotiqModel,
        object_width_m: Option<f64>,
        options: RobotiqEmulatorOptions,
    ) -> Result<RobotiqEmulator, DeviceError> {
        let (actuator, monitor) =
            kinematic_gripper(model.spec(), object_width_m, Arc::new(WallClock::start()));
        RobotiqEmulator::start(Box::new(actuator), Box::new(monitor), options)
    }

    /// The device side's path (`/dev/pts/N`), to open as the gripper's port.
    pub fn path(&self) -> &str {
        &self.path
    }

    /// What the emulator saw and did so far.
    pub fn record(&self) -> EmulatorRecord {
        *lock(&self.shared.record)
    }

    /// Reports `gFLT = code` from the next request on.
    pub fn inject_fault(&self, code: u8) {
        self.shared.fault.store(code, Ordering::SeqCst);
    }

    /// Stops answering; the terminal stays open.
    pub fn go_silent(&self) {
        self.shared.silent.store(true, Ordering::SeqCst);
    }

    /// Unplugs the adapter: the terminal closes, the host sees a hang-up.
    pub fn unplug(&self) {
        self.shared.unplug.store(true, Ordering::SeqCst);
    }
}

impl Drop for RobotiqEmulator {
    fn drop(&mut self) {
        self.shared.stop.store(true, Ordering::SeqCst);
        if let Some(t) = self.thread.take()
            && t.join().is_err()
        {
            tracing::warn!("{}: the Robotiq emulator thread panicked", self.path);
        }
    }
}

/// Longest wait for bytes before looking at the flags and the clock again.
const POLL: Duration = Duration::from_millis(2);
/// Silence after which an incomplete frame is dropped (or a frame of an
/// unknown function taken as complete).
const FRAME_GAP: Duration = Duration::from_millis(20);
/// Longest wait for the host to take a response.
const WRITE_TIMEOUT: Duration = Duration::from_millis(200);

struct Worker {
    master: TTYPort,
    /// Held so that the master never sees a hang-up while the host reopens.
    _slave: TTYPort,
    server: GripperServer,
    options: RobotiqEmulatorOptions,
    shared: Arc<Shared>,
    buf: Vec<u8>,
    last_byte: Instant,
    fault_done: bool,
}

impl Worker {
    fn run(mut self) {
        let mut chunk = [0u8; MAX_FRAME];
        while !self.shared.stop.load(Ordering::SeqCst) {
            let now = Instant::now();
            self.server.tick(now);
            if self.scheduled_faults(now) {
                tracing::info!("robotiq emulator: unplugging");
                return; // dropping the pseudo-terminal hangs up the device side
            }
            let read = self
                .master
                .set_timeout(POLL)
                .map_err(std::io::Error::from)
                .and_then(|()| self.master.read(&mut chunk));
            match read {
                Ok(n) => {
                    self.buf.extend_from_slice(&chunk[..n]);
                    self.last_byte = Instant::now();
                }
                Err(e)
                    if matches!(e.kind(), std::io::ErrorKind::TimedOut | std::io::ErrorKind::WouldBlock) => {}
                Err(e) => {
                    tracing::warn!("robotiq emulator: reading failed: {e}");
                    return;
                }
            }
            if !self.frames() {
                return;
            }
        }
    }

    /// Applies the scheduled and injected faults; true to unplug now.
    fn scheduled_faults(&mut self, now: Instant) -> bool {
        let injected = self.shared.fault.swap(0, Ordering::SeqCst);
        if injected != 0 {
            self.server.inject_fault(injected);
        }
        let Some(active) = self.server.active_since() else {
            return self.shared.unplug.load(Ordering::SeqCst);
        };
        let due = |after: Option<Duration>| after.is_some_and(|a| now.duration_since(active) >= a);
        if let Some((after, code)) = self.options.fault
            && !self.fault_done
            && due(Some(after))
        {
            self.fault_done = true;
            self.server.inject_fault(code);
        }
        if due(self.options.silent_after) {
            self.shared.silent.store(true, Ordering::SeqCst);
        }
        due(self.options.unplug_after) || self.shared.unplug.load(Ordering::SeqCst)
    }

    /// Answers the complete frames in the buffer; false when the host can
    /// no longer be written to.
    fn frames(&mut self) -> bool {
        loop {
            let silent_since = self.last_byte.elapsed() >= FRAME_GAP;
            let len = match request_len(&self.buf) {
                _ if self.buf.is_empty() => return true,
                Ok(Some(len)) if len <= self.buf.len() => len,
                Ok(Some(len)) if len > MAX_FRAME => self.buf.len(),
                // A frame of an unknown function ends at the silence.
                Err(_) if silent_since => self.buf.len(),
                _ if silent_since => {
                    self.buf.clear();
                    lock(&self.shared.record).ignored += 1;
                    return true;
                }
                _ => return true,
            };
            let frame: Vec<u8> = self.buf.drain(..len).collect();
            if !self.handle(&frame) {
                return false;
            }
        }
    }

    /// Answers one frame; false when the host can no longer be written to.
    fn handle(&mut self, frame: &[u8]) -> bool {
        let id = self.options.device_id;
        let reply = match Request::decode(frame) {
            Ok((to, request)) if to == id => match self.server.answer(&request, Instant::now()) {
                Ok(response) => Some(response.encode(id, request.function())),
                Err(code) => self.exception(request.function(), code),
            },
            Err(FrameError::UnknownFunction { device_id, function }) if device_id == id => {
                self.exception(function, crate::robotiq::modbus::exception::ILLEGAL_FUNCTION)
            }
            Err(FrameError::BadCrc { .. }) => {
                // The rest of the buffer may be out of step: drop it too.
                self.buf.clear();
                None
            }
            _ => None,
        };
        let mut record = lock(&self.shared.record);
        record.server = self.server.record();
        let Some(mut reply) = reply.filter(|_| !self.shared.silent.load(Ordering::SeqCst)) else {
            record.ignored += 1;
            return true;
        };
        record.answered += 1;
        let n = self.options.corrupt_every;
        if n > 0 && record.answered.is_multiple_of(n) {
            let at = (record.answered as usize / n as usize) % reply.len();
            reply[at] ^= 0x20;
        }
        drop(record);
        self.pace(frame.len(), reply.len());
        self.write(&reply)
    }

    fn exception(&mut self, function: u8, code: u8) -> Option<Vec<u8>> {
        if !self.options.exceptions {
            return None;
        }
        lock(&self.shared.record).exceptions += 1;
        Some(Response::Exception { function, code }.encode(self.options.device_id, function))
    }

    /// Waits as long as the request and the response take on the line,
    /// with the silences before and after the response.
    fn pace(&self, request_bytes: usize, response_bytes: usize) {
        if let Some(baud) = self.options.pace_baud.filter(|&b| b > 0) {
            let bits = 10.0 * (request_bytes + response_bytes) as f64;
            std::thread::sleep(Duration::from_secs_f64(bits / f64::from(baud)) + 2 * self.options.gap);
        }
    }

    fn write(&mut self, bytes: &[u8]) -> bool {
        if let Err(e) = self.master.set_timeout(WRITE_TIMEOUT) {
            tracing::warn!("robotiq emulator: {e}");
        }
        match self.master.write_all(bytes) {
            Ok(()) => true,
            Err(e) if e.kind() == std::io::ErrorKind::TimedOut => true,
            Err(e) => {
                if !self.shared.stop.load(Ordering::SeqCst) {
                    tracing::warn!("robotiq emulator: writing failed: {e}");
                }
                false
            }
        }
    }
}

#[cfg(test)]
mod tests;
