//! What every emulated device shares: the name that selects an emulator
//! (`port = "emulated"`), the check that the configured sensors are the
//! simulated ones, and [`Emulated`], a device's own reader in front of its
//! emulator.

use slidetrack_core::{DecoderCounters, DeviceError, ErrorKind, TactileInfo, TactileSample, TactileSource};

use crate::sensors::HwSensor;

/// The port name that selects the emulator instead of a device.
pub const EMULATED_PORT: &str = "emulated";

/// An emulator serving the simulated rig's scans to other programs, where
/// they would find the device.
pub struct ServedEmulator {
    /// Where to find it: a pseudo-terminal's path or a URL.
    pub endpoint: String,
    /// The running emulator; dropping it stops it.
    pub emulator: Box<dyn Send>,
}

/// A device's reader (`T`: the backend a real device is read with) in front
/// of its emulator (`E`: a pseudo-terminal or a local server fed by the
/// simulated rig). It reads as `T` does; dropping it closes the reader's
/// port or connection first, then stops the emulator.
pub struct Emulated<T, E> {
    /// Declared first: dropped before the emulator it reads.
    reader: T,
    emulator: E,
}

impl<T, E> Emulated<T, E> {
    /// `reader`, connected to `emulator`.
    pub fn new(reader: T, emulator: E) -> Emulated<T, E> {
        Emulated { reader, emulator }
    }

    /// The emulator behind the reader.
    pub fn emulator(&self) -> &E {
        &self.emulator
    }
}

impl<T: TactileSource, E: Send> TactileSource for Emulated<T, E> {
    /// # Contract
    /// As `T`'s: the bytes or messages come through a real tty or socket.
    fn read(&mut self) -> Result<TactileSample, DeviceError> {
        self.reader.read()
    }

    fn info(&self) -> TactileInfo {
        self.reader.info()
    }

    fn counters(&self) -> Option<DecoderCounters> {
        self.reader.counters()
    }
}

/// The configured sensors, `(name, rows, cols)`, must be the simulated ones
/// taxel for taxel: an emulator sends what the simulator measures, nothing
/// invented. The error names `device` (the emulated port or URL).
pub fn check_emulated_sensors(
    sim: &TactileInfo,
    configured: &[(&str, u32, u32)],
    device: &str,
) -> Result<(), DeviceError> {
    let sim_sensors = &sim.layout.sensors;
    let mismatch = sim_sensors.len() != configured.len()
        || sim_sensors.iter().zip(configured).any(|(a, &(_, r, c))| a.taxels() != (r * c) as usize);
    if !mismatch {
        return Ok(());
    }
    let describe = |v: Vec<(&str, u32, u32)>| {
        v.iter().map(|(n, r, c)| format!("{n} {r}x{c}")).collect::<Vec<_>>().join(", ")
    };
    let sim = describe(sim_sensors.iter().map(|s| (s.name.as_str(), s.rows, s.cols)).collect());
    let hw = describe(configured.to_vec());
    Err(DeviceError::new(
        ErrorKind::Other,
        device,
        format!(
            "hw.tactile.sensors ({hw}) must match the simulated sensors ({sim}) taxel for taxel: \
             set rows and cols, or a [sim.tactile.patch]"
        ),
    ))
}

/// `(name, rows, cols)` of configured sensors, for [`check_emulated_sensors`].
pub fn sensor_grids(sensors: &[HwSensor]) -> Vec<(&str, u32, u32)> {
    sensors.iter().map(|s| (s.name.as_str(), s.rows, s.cols)).collect()
}
