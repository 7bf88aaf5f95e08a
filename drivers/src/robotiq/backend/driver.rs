//! The Robotiq gripper behind the driver traits: activation when opened,
//! then a worker thread (`robotiq-link`) that owns the port and runs one
//! transaction after another: the newest position request with a status
//! read (FC23, or FC16 then FC03), or a status read alone.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use slidetrack_core::{
    ActuatorCommand, ActuatorSpec, Clock, DeviceError, ErrorKind, GripperRequest, GripperSpec, HandActuator,
    HandMonitor, HandStatus,
};

use super::link::{LinkCounters, RtuLink};
use crate::robotiq::config::RobotiqConfig;
use crate::robotiq::modbus::{Request, Response};
use crate::robotiq::registers::{REGISTERS, REQUEST_ADDRESS, RobotiqRequest, RobotiqStatus, STATUS_ADDRESS};

/// Time between two status reads while waiting for the activation.
const ACTIVATION_POLL: Duration = Duration::from_millis(20);

/// The write of the request registers (FC16).
pub fn write_request(request: &RobotiqRequest) -> Request {
    Request::WriteMultiple { address: REQUEST_ADDRESS, values: request.to_registers().to_vec() }
}

/// The read of the status registers (FC3).
pub fn read_status() -> Request {
    Request::ReadHolding { address: STATUS_ADDRESS, count: REGISTERS }
}

/// The write of the request registers and the read of the status in one
/// transaction (FC23).
pub fn write_request_read_status(request: &RobotiqRequest) -> Request {
    Request::ReadWriteMultiple {
        read_address: STATUS_ADDRESS,
        read_count: REGISTERS,
        write_address: REQUEST_ADDRESS,
        values: request.to_registers().to_vec(),
    }
}

/// A status from the registers of a read response.
fn status_of(response: &Response) -> Option<RobotiqStatus> {
    match response {
        Response::Registers(r) if r.len() == usize::from(REGISTERS) => {
            Some(RobotiqStatus::from_registers([r[0], r[1], r[2]]))
        }
        _ => None,
    }
}

/// Resets the gripper (`rACT = 0`), sets `rACT = 1` and waits until it
/// reports `gSTA = 3`. On a 2F gripper the fingers move while it activates.
/// Errors: a fault reported meanwhile (`Fault`), no activation within
/// `timeout` (`Timeout`), the link's errors.
pub fn activate(link: &mut RtuLink, timeout: Duration) -> Result<RobotiqStatus, DeviceError> {
    link.transact(&write_request(&RobotiqRequest::reset()))?;
    link.transact(&write_request(&RobotiqRequest::activate()))?;
    let deadline = Instant::now() + timeout;
    loop {
        match link.transact(&read_status()).map(|r| status_of(&r)) {
            Ok(Some(s)) if s.fault_message().is_some() && s.fault != 0x05 => {
                let fault = s.fault_message().unwrap_or_default();
                return Err(DeviceError::new(
                    ErrorKind::Fault,
                    link.device(),
                    format!("activation failed: {fault}"),
                ));
            }
            Ok(Some(s)) if s.is_active() => return Ok(s),
            Err(e) if e.kind == ErrorKind::Disconnected => return Err(e),
            _ if Instant::now() >= deadline => {
                let ms = timeout.as_millis();
                let detail = format!("the gripper did not finish its activation (gSTA = 3) within {ms} ms");
                return Err(DeviceError::new(ErrorKind::Timeout, link.device(), detail));
            }
            _ => std::thread::sleep(ACTIVATION_POLL),
        }
    }
}

struct Shared {
    /// The newest request not yet sent.
    pending: Mutex<Option<RobotiqRequest>>,
    state: Mutex<LinkState>,
    stop: AtomicBool,
    running: AtomicBool,
}

#[derive(Default)]
struct LinkState {
    latest: Option<HandStatus>,
    /// Statuses published so far.
    published: u64,
    /// The first error that ends the driver's use (sticky).
    error: Option<DeviceError>,
    counters: LinkCounters,
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

/// The thread that owns the port; dropping it stops the thread once the
/// pending request (if any) has been sent.
struct Poller {
    shared: Arc<Shared>,
    thread: Option<JoinHandle<()>>,
    device: String,
}

impl Poller {
    fn start(link: RtuLink, cfg: &RobotiqConfig, clock: Arc<dyn Clock>) -> Result<Poller, DeviceError> {
        let device = link.device().to_string();
        let shared = Arc::new(Shared {
            pending: Mutex::new(None),
            state: Mutex::new(LinkState::default()),
            stop: AtomicBool::new(false),
            running: AtomicBool::new(true),
        });
        let worker = Worker {
            link,
            shared: Arc::clone(&shared),
            clock,
            spec: cfg.model.spec(),
            poll_period: Duration::from_millis(cfg.poll_period_ms),
            link_timeout: Duration::from_millis(cfg.link_timeout_ms),
            read_write_in_one: cfg.read_write_in_one,
        };
        let thread =
            std::thread::Builder::new().name("robotiq-link".into()).spawn(move || worker.run()).map_err(
                |e| DeviceError::new(ErrorKind::Other, &device, format!("cannot start the link thread: {e}")),
            )?;
        Ok(Poller { shared, thread: Some(thread), device })
    }
}

impl Drop for Poller {
    fn drop(&mut self) {
        self.shared.stop.store(true, Ordering::SeqCst);
        if let Some(t) = self.thread.take()
            && t.join().is_err()
        {
            tracing::warn!("{}: the Robotiq link thread panicked", self.device);
        }
    }
}

struct Worker {
    link: RtuLink,
    shared: Arc<Shared>,
    clock: Arc<dyn Clock>,
    spec: GripperSpec,
    poll_period: Duration,
    link_timeout: Duration,
    read_write_in_one: bool,
}

impl Worker {
    fn run(mut self) {
        let mut last_ok = Instant::now();
        loop {
            let stopping = self.shared.stop.load(Ordering::SeqCst);
            let pending = lock(&self.shared.pending).take();
            if stopping && pending.is_none() {
                break;
            }
            let started = Instant::now();
            let result = self.transaction(pending.as_ref());
            lock(&self.shared.state).counters = self.link.counters();
            match result {
                Ok(status) => {
                    last_ok = Instant::now();
                    self.publish(&status);
                }
                Err(e) => {
                    if let Some(request) = pending {
                        // Sent again next time, unless a newer one came meanwhile.
                        lock(&self.shared.pending).get_or_insert(request);
                    }
                    tracing::debug!("{e}");
                    if e.kind == ErrorKind::Disconnected {
                        self.fail(e);
                        break;
                    }
                    if last_ok.elapsed() >= self.link_timeout {
                        let ms = self.link_timeout.as_millis();
                        let detail = format!("no valid response for {ms} ms (last: {})", e.detail);
                        self.fail(DeviceError::new(ErrorKind::Timeout, self.link.device(), detail));
                    }
                    if stopping {
                        break;
                    }
                }
            }
            let next = started + self.poll_period;
            std::thread::sleep(next.saturating_duration_since(Instant::now()));
        }
        self.shared.running.store(false, Ordering::SeqCst);
    }

    /// One transaction: the request (if any) and a status read.
    fn transaction(&mut self, pending: Option<&RobotiqRequest>) -> Result<RobotiqStatus, DeviceError> {
        let response = match pending {
            Some(r) if self.read_write_in_one => self.link.transact(&write_request_read_status(r))?,
            Some(r) => {
                self.link.transact(&write_request(r))?;
                self.link.transact(&read_status())?
            }
            None => self.link.transact(&read_status())?,
        };
        status_of(&response).ok_or_else(|| {
            DeviceError::new(ErrorKind::Corrupt, self.link.device(), "a status read without three registers")
        })
    }

    fn publish(&self, s: &RobotiqStatus) {
        let status = HandStatus {
            t: self.clock.now(),
            finger_travel_m: Vec::new(),
            opening_m: Some(self.spec.stroke_m - f64::from(s.position) * self.spec.step_m()),
            gripper: Some(s.gripper_status()),
        };
        {
            let mut state = lock(&self.shared.state);
            state.latest = Some(status);
            state.published += 1;
        }
        if let Some(fault) = s.fault_message() {
            self.fail(DeviceError::new(ErrorKind::Fault, self.link.device(), fault));
        }
    }

    fn fail(&self, e: DeviceError) {
        let mut state = lock(&self.shared.state);
        if state.error.is_none() {
            tracing::warn!("{e}");
            state.error = Some(e);
        }
    }
}

/// A Robotiq 2F-85/2F-140/Hand-E on Modbus RTU.
pub struct RobotiqGripper {
    poller: Poller,
    spec: GripperSpec,
    release: RobotiqRequest,
    speed: u8,
    force: u8,
}

impl RobotiqGripper {
    /// Opens `cfg.port`, activates the gripper (reset, then `rACT = 1`,
    /// waiting for `gSTA = 3` up to `cfg.activation_timeout_ms`) and starts
    /// the link thread; statuses are timed on `clock`.
    pub fn open(cfg: &RobotiqConfig, clock: Arc<dyn Clock>) -> Result<RobotiqGripper, DeviceError> {
        cfg.validate().map_err(|e| DeviceError::new(ErrorKind::Other, &cfg.port, e.to_string()))?;
        let mut link = RtuLink::open(
            &cfg.port,
            cfg.baud,
            cfg.device_id,
            Duration::from_millis(cfg.response_timeout_ms),
        )?;
        activate(&mut link, Duration::from_millis(cfg.activation_timeout_ms))?;
        let release =
            RobotiqRequest::go_to(&GripperRequest { position_steps: 0, speed: cfg.speed, force: cfg.force });
        Ok(RobotiqGripper {
            poller: Poller::start(link, cfg, clock)?,
            spec: cfg.model.spec(),
            release,
            speed: cfg.speed,
            force: cfg.force,
        })
    }

    /// A monitor of this gripper's status (what the link thread last read).
    pub fn monitor(&self) -> RobotiqMonitor {
        RobotiqMonitor {
            shared: Arc::clone(&self.poller.shared),
            device: self.poller.device.clone(),
            seen: 0,
            _poller: None,
        }
    }

    /// A request to `position_steps` at the configured speed and force.
    pub fn position_request(&self, position_steps: u16) -> GripperRequest {
        GripperRequest { position_steps, speed: self.speed, force: self.force }
    }

    /// What the link has seen so far.
    pub fn counters(&self) -> LinkCounters {
        lock(&self.poller.shared.state).counters
    }

    fn error(&self) -> Option<DeviceError> {
        lock(&self.poller.shared.state).error.clone()
    }
}

impl HandActuator for RobotiqGripper {
    fn spec(&self) -> ActuatorSpec {
        ActuatorSpec::Gripper(self.spec.clone())
    }

    /// # Contract
    /// - Clamps the position to 255 and hands the request to the link
    ///   thread, which sends the newest one in its next transaction; never
    ///   waits for the link or the fingers.
    /// - After a fault, a lost port or a silent gripper the command is not
    ///   sent: the first such error (`Fault` naming the fault,
    ///   `Disconnected`, `Timeout`) is returned, then and afterwards.
    fn command(&mut self, command: &ActuatorCommand) -> Result<(), DeviceError> {
        let ActuatorCommand::Gripper(request) = command else {
            return Err(command.wrong_kind(&self.poller.device, "gripper requests"));
        };
        if let Some(e) = self.error() {
            return Err(e);
        }
        *lock(&self.poller.shared.pending) = Some(RobotiqRequest::go_to(request));
        Ok(())
    }

    /// Asks for the fully open position (`rPR = 0`) at the configured speed
    /// and force, also after an error; returns without waiting. Fails only
    /// when the link thread has ended (port gone).
    fn release(&mut self) -> Result<(), DeviceError> {
        *lock(&self.poller.shared.pending) = Some(self.release);
        if self.poller.shared.running.load(Ordering::SeqCst) {
            return Ok(());
        }
        Err(self.error().unwrap_or_else(|| {
            DeviceError::new(ErrorKind::Disconnected, &self.poller.device, "the link thread has ended")
        }))
    }

    fn device(&self) -> &str {
        &self.poller.device
    }
}

impl Drop for RobotiqGripper {
    /// The release is the last request: the link thread sends it, then stops.
    fn drop(&mut self) {
        *lock(&self.poller.shared.pending) = Some(self.release);
    }
}

/// The gripper's status as the link thread reads it.
pub struct RobotiqMonitor {
    shared: Arc<Shared>,
    device: String,
    /// Statuses seen by this monitor.
    seen: u64,
    /// The link thread, when this monitor polls without driving.
    _poller: Option<Poller>,
}

impl RobotiqMonitor {
    /// Watches the gripper on `cfg.port` without commanding it: no
    /// activation, only status reads (FC3). Only possible while no other
    /// Modbus master talks on the same line.
    pub fn watch(cfg: &RobotiqConfig, clock: Arc<dyn Clock>) -> Result<RobotiqMonitor, DeviceError> {
        cfg.validate().map_err(|e| DeviceError::new(ErrorKind::Other, &cfg.port, e.to_string()))?;
        let link = RtuLink::open(
            &cfg.port,
            cfg.baud,
            cfg.device_id,
            Duration::from_millis(cfg.response_timeout_ms),
        )?;
        let poller = Poller::start(link, cfg, clock)?;
        Ok(RobotiqMonitor {
            shared: Arc::clone(&poller.shared),
            device: poller.device.clone(),
            seen: 0,
            _poller: Some(poller),
        })
    }
}

impl HandMonitor for RobotiqMonitor {
    /// The newest status, `None` when the link thread has read none since
    /// the previous call; the port's loss as `Disconnected` (a fault is in
    /// the status, not an error here).
    fn status(&mut self) -> Result<Option<HandStatus>, DeviceError> {
        let state = lock(&self.shared.state);
        if state.published > self.seen {
            self.seen = state.published;
            return Ok(state.latest.clone());
        }
        match &state.error {
            Some(e) if e.kind == ErrorKind::Disconnected => Err(e.clone()),
            _ => Ok(None),
        }
    }

    fn device(&self) -> &str {
        &self.device
    }
}
