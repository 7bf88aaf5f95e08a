//! The `slcan = { ... }` table of a CAN tactile device: an SLCAN adapter on
//! a serial port instead of a SocketCAN interface.

use serde::{Deserialize, Serialize};

use crate::slcan::protocol::SlcanConfig;

/// An SLCAN adapter on a serial port (`slcan = { port = ... }`): the
/// settings of [`SlcanConfig`] beside the port.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SlcanTransport {
    /// The adapter's serial port (`/dev/ttyUSB0`, `/dev/ttyACM0`), or
    /// `emulated` for the pty emulator fed by the simulated rig.
    pub port: String,
    /// CAN bit rate (bit/s); default 1 000 000 (`S8`).
    pub bitrate: u32,
    /// Serial speed (baud); USB CDC adapters ignore it. Default 3 000 000.
    pub baud: u32,
    /// Ask for the adapter's timestamps (`Z1`); default true. CANable's
    /// slcan firmware has no `Z`: set false for it. (Samples are stamped on
    /// the host's arrival time either way.)
    pub timestamps: bool,
    /// Send `C`, `Sn`, `Z`, `O` at open and `C` at close; default true.
    pub setup: bool,
    /// RTS/CTS flow control; default true (XELA's setup runs `slcand -t hw`
    /// for the VScom USB-CAN Plus).
    pub hardware_flow_control: bool,
    /// Longest wait for the reply to a set-up command (ms).
    pub reply_timeout_ms: u64,
    /// Emulator faults (only with `port = "emulated"`): hang up this long
    /// after the first frames (s), as an unplugged adapter.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub unplug_after_s: Option<f64>,
}

impl Default for SlcanTransport {
    fn default() -> Self {
        let d = SlcanConfig::default();
        SlcanTransport {
            port: "/dev/ttyUSB0".into(),
            bitrate: d.bitrate,
            baud: d.baud,
            timestamps: d.timestamps,
            setup: d.setup,
            hardware_flow_control: d.hardware_flow_control,
            reply_timeout_ms: d.reply_timeout_ms,
            unplug_after_s: None,
        }
    }
}

impl SlcanTransport {
    /// The adapter settings.
    pub fn adapter(&self) -> SlcanConfig {
        SlcanConfig {
            baud: self.baud,
            bitrate: self.bitrate,
            timestamps: self.timestamps,
            setup: self.setup,
            hardware_flow_control: self.hardware_flow_control,
            reply_timeout_ms: self.reply_timeout_ms,
        }
    }
}
