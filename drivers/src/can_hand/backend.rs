//! The hand actuator on CAN: set-points, a heartbeat thread, and a release
//! sent on stop, on error and on drop (frame layout in [`crate::can_hand::protocol`]).

use std::sync::atomic::{AtomicU8, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::Duration;

use crossbeam_channel::{RecvTimeoutError, Sender};
use slidetrack_core::{ActuatorCommand, ActuatorSpec, DeviceError, ErrorKind, HandActuator, saturate};

use crate::can::backend::socketcan::{CanBus, SocketCanBus};
use crate::can_hand::config::CanHandConfig;
use crate::can_hand::protocol::{HandCanIds, HandState};
use crate::io_error_kind::io_error_kind;

/// The hand on a CAN bus.
pub struct CanHand {
    bus: Arc<dyn CanBus>,
    ids: HandCanIds,
    max_volts: f64,
    device: String,
    counter: u8,
    state: Arc<AtomicU8>,
    heartbeat: Option<Heartbeat>,
    failed: Option<DeviceError>,
}

struct Heartbeat {
    stop: Sender<()>,
    thread: JoinHandle<()>,
    error: Arc<Mutex<Option<DeviceError>>>,
}

impl CanHand {
    /// Opens `cfg.interface` and starts the heartbeat.
    pub fn open(cfg: &CanHandConfig) -> Result<CanHand, DeviceError> {
        CanHand::with_bus(Arc::new(SocketCanBus::open(&cfg.interface)?), cfg)
    }

    /// The hand on `bus`; starts the heartbeat thread (`hand-heartbeat`).
    pub fn with_bus(bus: Arc<dyn CanBus>, cfg: &CanHandConfig) -> Result<CanHand, DeviceError> {
        let device = format!("{} hand", bus.name());
        let ids = cfg.ids();
        ids.validate().map_err(|e| DeviceError::new(ErrorKind::Other, &device, e.to_string()))?;
        let state = Arc::new(AtomicU8::new(HandState::Idle as u8));
        let heartbeat = Heartbeat::start(
            Arc::clone(&bus),
            ids,
            Duration::from_millis(cfg.heartbeat_ms.max(1)),
            Arc::clone(&state),
            device.clone(),
        )?;
        Ok(CanHand {
            bus,
            ids,
            max_volts: cfg.max_volts,
            device,
            counter: 0,
            state,
            heartbeat: Some(heartbeat),
            failed: None,
        })
    }

    fn error(&self, e: &std::io::Error, what: &str) -> DeviceError {
        DeviceError::new(io_error_kind(e), &self.device, format!("{what}: {e}"))
    }

    fn send_release(&self) -> Result<(), DeviceError> {
        self.state.store(HandState::Released as u8, Ordering::SeqCst);
        self.bus.send(&self.ids.release()).map_err(|e| self.error(&e, "cannot send the release"))
    }

    fn heartbeat_error(&self) -> Option<DeviceError> {
        let hb = self.heartbeat.as_ref()?;
        hb.error.lock().ok().and_then(|e| e.clone())
    }
}

impl HandActuator for CanHand {
    /// # Contract
    /// - Saturates to `±max_volts`, sends one set-point frame and returns;
    ///   it never waits for the hand.
    /// - A failed send (or a failed heartbeat) is returned as the device's
    ///   error kind (`Disconnected` when the interface is gone); the hand is
    ///   sent a release right away, and later commands fail with the same error.
    fn command(&mut self, command: &ActuatorCommand) -> Result<(), DeviceError> {
        let ActuatorCommand::FingerVolts(volts) = *command else {
            return Err(command.wrong_kind(&self.device, "finger voltages"));
        };
        if let Some(e) = self.failed.clone().or_else(|| self.heartbeat_error()) {
            self.failed = Some(e.clone());
            return Err(e);
        }
        let frame = self.ids.setpoint(self.counter, saturate(volts, self.max_volts));
        self.counter = self.counter.wrapping_add(1);
        self.state.store(HandState::Commanding as u8, Ordering::SeqCst);
        if let Err(e) = self.bus.send(&frame) {
            let err = self.error(&e, "cannot send the set-point");
            if let Err(release) = self.send_release() {
                tracing::warn!("{release}");
            }
            self.failed = Some(err.clone());
            return Err(err);
        }
        Ok(())
    }

    /// Sends the release frame (the firmware opens the hand, then zeroes the
    /// voltage). Callable any number of times, also after an error.
    fn release(&mut self) -> Result<(), DeviceError> {
        self.send_release()
    }

    fn spec(&self) -> ActuatorSpec {
        ActuatorSpec::FingerVolts { max_volts: self.max_volts }
    }

    fn device(&self) -> &str {
        &self.device
    }
}

impl Drop for CanHand {
    /// Stops the heartbeat, then sends the release: the release is the last
    /// frame the hand gets from us.
    fn drop(&mut self) {
        self.state.store(HandState::Released as u8, Ordering::SeqCst);
        if let Some(hb) = self.heartbeat.take() {
            // Sending fails only when the thread is gone already.
            let _ = hb.stop.send(());
            if hb.thread.join().is_err() {
                tracing::warn!("{}: the heartbeat thread panicked", self.device);
            }
        }
        if let Err(e) = self.send_release() {
            tracing::warn!("releasing on drop: {e}");
        }
    }
}

impl Heartbeat {
    fn start(
        bus: Arc<dyn CanBus>,
        ids: HandCanIds,
        period: Duration,
        state: Arc<AtomicU8>,
        device: String,
    ) -> Result<Heartbeat, DeviceError> {
        let (stop, stopped) = crossbeam_channel::bounded::<()>(1);
        let error = Arc::new(Mutex::new(None));
        let slot = Arc::clone(&error);
        let name = device.clone();
        let thread = std::thread::Builder::new()
            .name("hand-heartbeat".into())
            .spawn(move || {
                let mut counter = 0u8;
                loop {
                    let s = match state.load(Ordering::SeqCst) {
                        0 => HandState::Idle,
                        1 => HandState::Commanding,
                        _ => HandState::Released,
                    };
                    if let Err(e) = bus.send(&ids.heartbeat(counter, s)) {
                        let err =
                            DeviceError::new(io_error_kind(&e), &name, format!("heartbeat failed: {e}"));
                        if let Ok(mut slot) = slot.lock() {
                            *slot = Some(err);
                        }
                        // The hand opens by itself when heartbeats stop; ask it now too.
                        let _ = bus.send(&ids.release());
                        return;
                    }
                    counter = counter.wrapping_add(1);
                    match stopped.recv_timeout(period) {
                        Err(RecvTimeoutError::Timeout) => {}
                        Ok(()) | Err(RecvTimeoutError::Disconnected) => return,
                    }
                }
            })
            .map_err(|e| {
                DeviceError::new(ErrorKind::Other, &device, format!("cannot start the heartbeat: {e}"))
            })?;
        Ok(Heartbeat { stop, thread, error })
    }
}
