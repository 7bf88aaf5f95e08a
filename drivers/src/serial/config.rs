//! The `[hw.tactile]` table of `kind = "serial"`: uSkin-style modules
//! streaming the serial format, or the simulated rig behind the serial
//! emulator (`port = "emulated"`).

use serde::{Deserialize, Serialize};
use slidetrack_core::{FingerReading, PerFinger};

use crate::config::error::{HwConfigError, check};
use crate::sensors::{HwSensor, default_sensors, validate_sensors};
use crate::serial::protocol::MAX_TAXELS;

/// uSkin-style modules on a serial port.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SerialTactileConfig {
    /// Device path (`/dev/ttyACM0`), or `emulated` for the simulated rig
    /// streaming the same bytes through a pseudo-terminal.
    pub port: String,
    /// Baud rate (ignored by USB CDC devices and pseudo-terminals).
    pub baud: u32,
    /// Nominal scan rate (Hz), recorded in the taxel layout. The emulator
    /// runs at the `[sim]` tactile rate instead.
    pub rate_hz: f64,
    /// Taxels in each module's frame.
    pub taxels_per_module: u16,
    /// Longest wait for a scan once streaming (ms).
    pub timeout_ms: u64,
    /// Longest wait for the first scan after opening the port (ms).
    pub startup_timeout_ms: u64,
    /// The sensors: which modules are read, their layout and finger.
    pub sensors: Vec<HwSensor>,
    /// What each finger's reading is (a taxel of a sensor, or its mean);
    /// without it, taxel 0 of the sensor whose `finger` names the finger
    /// ([`crate::sensors::finger_readings`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fingers: Option<PerFinger<FingerReading>>,
    /// Faults the emulator injects (only with `port = "emulated"`).
    pub emulator: EmulatorConfig,
}

impl Default for SerialTactileConfig {
    fn default() -> Self {
        SerialTactileConfig {
            port: "/dev/ttyACM0".into(),
            baud: 921_600,
            rate_hz: 100.0,
            taxels_per_module: 16,
            timeout_ms: 50,
            startup_timeout_ms: 2000,
            sensors: default_sensors(4, 4),
            fingers: None,
            emulator: EmulatorConfig::default(),
        }
    }
}

/// Faults the serial emulator injects, for tests and demonstrations.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct EmulatorConfig {
    /// Close the pseudo-terminal (as if the device were unplugged) this long
    /// after the first scan (s).
    pub unplug_after_s: Option<f64>,
    /// Flip a payload bit in every n-th frame (0: never).
    pub corrupt_every_frames: u32,
    /// Insert a few bytes of garbage before every n-th frame (0: never).
    pub garbage_every_frames: u32,
}

impl SerialTactileConfig {
    /// The checks that serde's types cannot make.
    pub fn validate(&self) -> Result<(), HwConfigError> {
        let s = self;
        check("tactile.rate_hz", s.rate_hz, s.rate_hz.is_finite() && s.rate_hz > 0.0, "> 0 Hz")?;
        let n = f64::from(s.taxels_per_module);
        let ok = (1..=MAX_TAXELS).contains(&usize::from(s.taxels_per_module));
        check("tactile.taxels_per_module", n, ok, "1..=64")?;
        check("tactile.timeout_ms", s.timeout_ms as f64, s.timeout_ms > 0, "> 0 ms")?;
        validate_sensors(&s.sensors, s.fingers.as_ref(), usize::from(s.taxels_per_module))?;
        if let Some(big) = s.sensors.iter().find(|x| x.module > 255) {
            check("tactile.sensors.module", f64::from(big.module), false, "0..=255")?;
        }
        if let Some(t) = s.emulator.unplug_after_s {
            check("tactile.emulator.unplug_after_s", t, t.is_finite() && t >= 0.0, ">= 0 s")?;
        }
        Ok(())
    }
}
