//! A CAN tactile device made of the simulated rig behind an SLCAN adapter
//! made of a pseudo-terminal (`slcan = { port = "emulated" }`): the
//! simulated sensors' scans are encoded in the configured layout, streamed
//! by [`SlcanEmulator`] as an adapter would, and read back by
//! [`SlcanBus`] and [`CanTactile`] exactly as from a real adapter.

use std::sync::Arc;
use std::time::Duration;

use slidetrack_core::{Clock, DeviceError, ErrorKind, TactileSource};

use crate::can::backend::CanTactile;
use crate::can::config::CanTactileConfig;
use crate::emulated::EMULATED_PORT;
use crate::emulated::{Emulated, check_emulated_sensors, sensor_grids};
use crate::slcan::backend::SlcanBus;
use crate::slcan::backend::emulator::{FrameSource, SlcanEmulator, SlcanEmulatorConfig};

/// The CAN backend reading the SLCAN emulator. Dropping it sends the stop
/// frames and closes the adapter's channel, then stops the emulator; what
/// the emulated adapter saw (commands, transmitted frames) is
/// `emulator().record()`.
pub type EmulatedSlcanTactile = Emulated<CanTactile, SlcanEmulator>;

impl Emulated<CanTactile, SlcanEmulator> {
    /// Starts the emulator streaming `source`'s scans in `cfg`'s layout,
    /// then opens its pseudo-terminal as the adapter's port with `cfg`'s
    /// SLCAN settings (its `port` ignored) and sends the start frames.
    /// `rate_hz` (the simulated rate) is recorded in the layout.
    pub fn start(
        mut source: Box<dyn TactileSource>,
        cfg: &CanTactileConfig,
        rate_hz: f64,
        clock: Arc<dyn Clock>,
    ) -> Result<EmulatedSlcanTactile, DeviceError> {
        check_emulated_sensors(&source.info(), &sensor_grids(&cfg.sensors), EMULATED_PORT)?;
        let layout =
            cfg.layout().map_err(|e| DeviceError::new(ErrorKind::Other, EMULATED_PORT, e.to_string()))?;
        let transport = cfg.slcan.clone().unwrap_or_default();
        let frames: FrameSource = Box::new(move || match source.read() {
            Ok(sample) => Some(layout.encode_scan(&sample.raw)),
            Err(e) => {
                tracing::warn!("slcan emulator: the simulated source failed: {e}");
                None
            }
        });
        let emu_cfg = SlcanEmulatorConfig {
            period: Duration::from_millis(1),
            timestamps_supported: true,
            unplug_after: transport.unplug_after_s.map(Duration::from_secs_f64),
            ..SlcanEmulatorConfig::default()
        };
        let emulator = SlcanEmulator::start(frames, emu_cfg)?;
        let bus = SlcanBus::open(emulator.path(), &transport.adapter())?;
        let tactile = CanTactile::with_bus(Arc::new(bus), cfg, rate_hz, clock)?;
        Ok(Emulated::new(tactile, emulator))
    }
}

/// The SLCAN emulator alone, streaming `source`'s scans in `cfg`'s layout
/// with the adapter's default settings, for programs that open the
/// adapter themselves (`slidetrack emulate slcan`).
pub fn serve(
    mut source: Box<dyn TactileSource>,
    cfg: &CanTactileConfig,
) -> Result<SlcanEmulator, DeviceError> {
    check_emulated_sensors(&source.info(), &sensor_grids(&cfg.sensors), "slcan emulator")?;
    let layout = cfg.layout().map_err(|e| DeviceError::new(ErrorKind::Other, "hw.tactile", e.to_string()))?;
    let frames: FrameSource = Box::new(move || source.read().ok().map(|s| layout.encode_scan(&s.raw)));
    SlcanEmulator::start(frames, SlcanEmulatorConfig::default())
}
