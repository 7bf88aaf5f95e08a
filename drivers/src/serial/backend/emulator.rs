//! A serial tactile device made of the simulated rig: it streams a
//! [`TactileSource`]'s scans as frames of the serial format into a
//! pseudo-terminal, whose other end the serial backend opens like a real
//! device. Faults (corrupt frames, garbage, unplugging) can be injected.

use std::io::Write;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use serialport::{SerialPort, TTYPort};
use slidetrack_core::{Clock, DeviceError, ErrorKind, RawTaxel, TactileSource};

use super::device::SerialTactile;
use crate::emulated::{EMULATED_PORT, Emulated, check_emulated_sensors, sensor_grids};
use crate::serial::config::{EmulatorConfig, SerialTactileConfig};
use crate::serial::protocol::{FrameEncodeError, MAX_TAXELS, ModuleFrame, SYNC};

/// Garbage written before a frame when asked to: contains a false sync.
const GARBAGE: [u8; 7] = [0x00, SYNC[0], SYNC[1], 0xFF, 0x13, SYNC[0], 0x42];

/// A pseudo-terminal waiting for its device side to start streaming.
pub struct EmulatedPort {
    master: TTYPort,
    slave: TTYPort,
    path: String,
}

impl EmulatedPort {
    /// Creates the pseudo-terminal pair; the device path is [`EmulatedPort::path`].
    pub fn open() -> Result<EmulatedPort, DeviceError> {
        let (master, slave) = TTYPort::pair().map_err(|e| {
            DeviceError::new(
                ErrorKind::Other,
                "serial emulator",
                format!("cannot create a pseudo-terminal: {e}"),
            )
        })?;
        let path = slave.name().ok_or_else(|| {
            DeviceError::new(ErrorKind::Other, "serial emulator", "the pseudo-terminal has no device path")
        })?;
        Ok(EmulatedPort { master, slave, path })
    }

    /// The path of the device side (`/dev/pts/N`), to open as a serial port.
    pub fn path(&self) -> &str {
        &self.path
    }

    /// Starts streaming `source`'s scans on a thread named `serial-emulator`:
    /// per scan, one frame per sensor of the source, on module `modules[i]`
    /// for its `i`-th sensor, `taxels_per_module` taxels each (the sensor's
    /// taxels first, fixed filler values after them), the source's sequence
    /// counter as scan counter.
    pub fn stream(
        self,
        source: Box<dyn TactileSource>,
        modules: Vec<u32>,
        taxels_per_module: u16,
        faults: EmulatorConfig,
    ) -> Result<SerialEmulator, DeviceError> {
        let stop = Arc::new(AtomicBool::new(false));
        let path = self.path.clone();
        let sensors: Vec<(u32, std::ops::Range<usize>)> =
            modules.into_iter().zip(source.info().layout.sensor_ranges().map(|(_, r)| r)).collect();
        let worker = Worker {
            port: self,
            source,
            sensors,
            taxels_per_module: usize::from(taxels_per_module).clamp(1, MAX_TAXELS),
            faults,
            stop: Arc::clone(&stop),
        };
        let thread =
            std::thread::Builder::new().name("serial-emulator".into()).spawn(move || worker.run()).map_err(
                |e| DeviceError::new(ErrorKind::Other, &path, format!("cannot start the emulator: {e}")),
            )?;
        Ok(SerialEmulator { path, stop, thread: Some(thread) })
    }
}

/// The running emulator; dropping it stops the stream and closes the terminal.
pub struct SerialEmulator {
    path: String,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl SerialEmulator {
    /// The device path the serial backend opened.
    pub fn path(&self) -> &str {
        &self.path
    }
}

impl Drop for SerialEmulator {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        if let Some(t) = self.thread.take()
            && t.join().is_err()
        {
            tracing::warn!("{}: the serial emulator thread panicked", self.path);
        }
    }
}

/// The serial backend reading an emulator: a [`SerialTactile`] on the
/// device side of a pseudo-terminal fed by the simulated rig. Dropping it
/// closes the port, then stops the emulator.
pub type EmulatedSerialTactile = Emulated<SerialTactile, SerialEmulator>;

impl Emulated<SerialTactile, SerialEmulator> {
    /// Creates the pseudo-terminal, opens its device side with the serial
    /// backend (`cfg` as for a real port, its `port` ignored), then starts
    /// streaming `source` into it, with `cfg.emulator`'s faults.
    pub fn start(
        source: Box<dyn TactileSource>,
        cfg: &SerialTactileConfig,
        rate_hz: f64,
        clock: Arc<dyn Clock>,
    ) -> Result<EmulatedSerialTactile, DeviceError> {
        check_emulated_sensors(&source.info(), &sensor_grids(&cfg.sensors), EMULATED_PORT)?;
        let port = EmulatedPort::open()?;
        let tactile = SerialTactile::open(port.path(), cfg, rate_hz, clock)?;
        let modules = cfg.sensors.iter().map(|s| s.module).collect();
        let emulator = port.stream(source, modules, cfg.taxels_per_module, cfg.emulator.clone())?;
        Ok(Emulated::new(tactile, emulator))
    }
}

struct Worker {
    port: EmulatedPort,
    source: Box<dyn TactileSource>,
    /// Per sensor of the source: its module and its taxels in a scan.
    sensors: Vec<(u32, std::ops::Range<usize>)>,
    taxels_per_module: usize,
    faults: EmulatorConfig,
    stop: Arc<AtomicBool>,
}

impl Worker {
    fn run(mut self) {
        let unplug_after = self.faults.unplug_after_s.map(Duration::from_secs_f64);
        let mut first_scan: Option<Instant> = None;
        let mut frames = 0u64;
        let mut bytes = Vec::new();
        // Writes must not block forever if nobody reads the other end.
        if let Err(e) = self.port.master.set_timeout(Duration::from_millis(500)) {
            tracing::warn!("serial emulator: {e}");
        }
        while !self.stop.load(Ordering::SeqCst) {
            if let (Some(start), Some(after)) = (first_scan, unplug_after)
                && start.elapsed() >= after
            {
                tracing::info!("serial emulator: unplugging {}", self.port.path);
                return; // dropping the pseudo-terminal hangs up the device side
            }
            let sample = match self.source.read() {
                Ok(s) => s,
                Err(e) => {
                    tracing::warn!("serial emulator: the simulated source failed: {e}");
                    return;
                }
            };
            first_scan.get_or_insert_with(Instant::now);
            bytes.clear();
            for (module, taxels) in &self.sensors {
                frames += 1;
                let f = &self.faults;
                if f.garbage_every_frames > 0 && frames.is_multiple_of(u64::from(f.garbage_every_frames)) {
                    bytes.extend_from_slice(&GARBAGE);
                }
                let start = bytes.len();
                match self.module_frame(
                    *module,
                    sample.raw.get(taxels.clone()).unwrap_or(&[]),
                    sample.sequence,
                ) {
                    Ok(frame) => frame.encode_into(&mut bytes),
                    Err(e) => {
                        tracing::warn!("serial emulator: {e}");
                        return;
                    }
                }
                if f.corrupt_every_frames > 0 && frames.is_multiple_of(u64::from(f.corrupt_every_frames)) {
                    bytes[start + 9] ^= 0x04; // a payload bit
                }
            }
            match self.port.master.write_all(&bytes) {
                Ok(()) => {}
                // Nobody reads the device side (yet): the bytes are lost, as
                // a device's full output buffer would lose them.
                Err(e) if e.kind() == std::io::ErrorKind::TimedOut => {}
                Err(e) => {
                    if !self.stop.load(Ordering::SeqCst) {
                        tracing::warn!("serial emulator: writing to {} failed: {e}", self.port.path);
                    }
                    return;
                }
            }
        }
        // Keep the device side open until here so that the reader never
        // sees a hang-up before the emulator stops.
        drop(self.port.slave);
    }

    fn module_frame(
        &self,
        module: u32,
        values: &[RawTaxel],
        sequence: u64,
    ) -> Result<ModuleFrame, FrameEncodeError> {
        let taxels: Vec<RawTaxel> = (0..self.taxels_per_module)
            .map(|t| {
                values.get(t).copied().unwrap_or_else(|| {
                    let filler = 1000 * (module as u16 % 60) + 10 * t as u16;
                    [filler, filler + 1, filler + 2]
                })
            })
            .collect();
        ModuleFrame::new(module as u8, sequence as u16, &taxels)
    }
}

#[cfg(test)]
mod tests;
