//! `kind = "xela_ws"`: the `[hw.tactile]` table of sensors read through
//! XELA's `xela_server` (WebSocket JSON, see `docs/protocols.md`).
//!
//! ```toml
//! [hw.tactile]
//! kind = "xela_ws"
//! url = "ws://127.0.0.1:5000"    # "emulated": the simulated rig behind a local server
//! rate_hz = 100.0                # nominal, recorded in the layout
//! [[hw.tactile.sensors]]
//! name = "left"
//! sensor = 1                     # the server's sensor number (its key "1" in the messages)
//! finger = "thumb"
//! model = "uSPa44"               # what the server must report, with rows x cols taxels
//! rows = 4
//! cols = 4
//! ```

use serde::{Deserialize, Serialize};
use slidetrack_core::{Finger, FingerReading, PerFinger, TactileInfo};

use super::protocol::{Expected, ExpectedSensor, WireStyle};
use crate::sensors::{HwSensor, SensorConfigError, tactile_info, validate_sensors};

/// The URL that selects the local emulator fed by the simulated rig.
pub const EMULATED_URL: &str = "emulated";

/// Sensors read through `xela_server`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct XelaWsTactileConfig {
    /// The server's WebSocket (`ws://HOST:PORT`, port 5000 when none is
    /// given), or `emulated` for the simulated rig behind a local server.
    pub url: String,
    /// Nominal scan rate (Hz), recorded in the taxel layout (the server's
    /// rate is set in its xServ.ini, not here). The emulator runs at the
    /// `[sim]` tactile rate instead.
    pub rate_hz: f64,
    /// Longest wait for a scan once streaming (ms).
    pub timeout_ms: u64,
    /// Longest wait for the first scan after connecting (ms).
    pub startup_timeout_ms: u64,
    /// Limit of one TCP connection and WebSocket handshake (ms).
    pub connect_timeout_ms: u64,
    /// How a lost connection is re-established (also the first one).
    pub reconnect: XelaReconnectConfig,
    /// The sensors: which server sensor each is, its model, grid and finger.
    pub sensors: Vec<XelaSensor>,
    /// What each finger's reading is (a taxel of a sensor, or its mean);
    /// without it, taxel 0 of the sensor whose `finger` names the finger
    /// ([`crate::sensors::finger_readings`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fingers: Option<PerFinger<FingerReading>>,
    /// What the emulator sends and the faults it injects (only with `url = "emulated"`).
    pub emulator: XelaEmulatorConfig,
}

impl Default for XelaWsTactileConfig {
    fn default() -> Self {
        XelaWsTactileConfig {
            url: format!("ws://127.0.0.1:{}", super::protocol::DEFAULT_PORT),
            rate_hz: 100.0,
            timeout_ms: 200,
            startup_timeout_ms: 5000,
            connect_timeout_ms: 1000,
            reconnect: XelaReconnectConfig::default(),
            sensors: default_xela_sensors(),
            fingers: None,
            emulator: XelaEmulatorConfig::default(),
        }
    }
}

/// `[hw.tactile.reconnect]`: the reconnection policy.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct XelaReconnectConfig {
    /// Wait before the second attempt (ms); the first is immediate.
    pub initial_backoff_ms: u64,
    /// Longest wait between attempts (ms); waits double up to it.
    pub max_backoff_ms: u64,
    /// Attempts after which the server counts as gone (0: never reconnect).
    pub max_attempts: u32,
    /// Time after the loss after which the server counts as gone (ms).
    pub max_duration_ms: u64,
}

impl Default for XelaReconnectConfig {
    /// Up to 20 attempts within 3 s, waits from 100 ms doubling up to 1 s:
    /// a trial's read blocks while the server is away, so the policy bounds
    /// how long the hand waits for data.
    fn default() -> Self {
        XelaReconnectConfig {
            initial_backoff_ms: 100,
            max_backoff_ms: 1000,
            max_attempts: 20,
            max_duration_ms: 3000,
        }
    }
}

/// One `[[hw.tactile.sensors]]` entry of a `xela_ws` rig.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct XelaSensor {
    /// Unique name (`left`, `thumb`), used in channel fields and dEKF channels.
    pub name: String,
    /// The server's number of the sensor: its key in the messages (`"1"`),
    /// the position xServ.ini gives it (`[sensor]` is 1, `[sensor2]` is 2).
    pub sensor: u32,
    /// The finger (or gripper pad) carrying it.
    pub finger: String,
    /// The model the server must report (`uSPa44`; compared without regard
    /// to letter case).
    pub model: String,
    /// Rows of taxels.
    pub rows: u32,
    /// Columns of taxels: the server must send `rows * cols` taxels, kept
    /// in the server's order, which is read as row by row.
    pub cols: u32,
    /// Taxel centres in the sensor frame (mm), in taxel order, when known.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub taxel_positions_mm: Option<Vec<[f64; 2]>>,
}

impl XelaSensor {
    /// As the sensor table the other backends use (`module` = server sensor number).
    pub fn hw_sensor(&self) -> HwSensor {
        HwSensor {
            name: self.name.clone(),
            module: self.sensor,
            finger: self.finger.clone(),
            model: self.model.clone(),
            rows: self.rows,
            cols: self.cols,
            taxel_positions_mm: self.taxel_positions_mm.clone(),
        }
    }

    /// Taxels the server must send.
    pub fn taxels(&self) -> usize {
        self.rows as usize * self.cols as usize
    }
}

/// Server sensors 1, 2, 3: uSPa44 (4 x 4) on thumb, index and middle finger.
pub fn default_xela_sensors() -> Vec<XelaSensor> {
    Finger::ALL
        .iter()
        .map(|f| XelaSensor {
            name: f.name().into(),
            sensor: f.index() as u32 + 1,
            finger: f.name().into(),
            model: "uSPa44".into(),
            rows: 4,
            cols: 4,
            taxel_positions_mm: None,
        })
        .collect()
}

/// How the emulator writes the raw counts (`hw.tactile.emulator.encoding`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum XelaEncoding {
    /// A list of integers (server 1.7.7 and later).
    #[default]
    List,
    /// A comma-separated hex string (server 1.7.6 and earlier).
    Hex,
    /// The hex string and an `integer` list (as captured from 1.8.0b).
    HexAndInteger,
}

impl XelaEncoding {
    /// The protocol's wire style.
    pub fn wire_style(self) -> WireStyle {
        match self {
            XelaEncoding::List => WireStyle::IntegerList,
            XelaEncoding::Hex => WireStyle::HexString,
            XelaEncoding::HexAndInteger => WireStyle::HexAndInteger,
        }
    }
}

/// `[hw.tactile.emulator]` of a `xela_ws` rig: what the local server fed by
/// the simulated rig sends, and its faults.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct XelaEmulatorConfig {
    /// The encoding of the raw counts.
    pub encoding: XelaEncoding,
    /// Drop the connection this long after the first scan (s).
    pub disconnect_after_s: Option<f64>,
    /// How long the server is then gone (s): it refuses connections and
    /// the scans of that time are lost. Absent: gone for good.
    pub down_for_s: Option<f64>,
    /// Send a malformed (truncated) message after every n-th scan (0: never).
    pub malformed_every: u32,
    /// Skip one message counter after every n-th scan (0: never).
    pub gap_every: u32,
    /// Report this model for the last configured sensor instead of its own.
    pub wrong_model: Option<String>,
}

impl XelaWsTactileConfig {
    /// The sensors as the other backends' table.
    pub fn hw_sensors(&self) -> Vec<HwSensor> {
        self.sensors.iter().map(XelaSensor::hw_sensor).collect()
    }

    /// What the source is: its layout and finger readings.
    pub fn info(&self, device: &str, rate_hz: f64) -> TactileInfo {
        tactile_info(device, rate_hz, &self.hw_sensors(), self.fingers.as_ref())
    }

    /// The sensors the server must send, for the decoder's check.
    pub fn expected(&self) -> Expected {
        Expected {
            sensors: self
                .sensors
                .iter()
                .map(|s| ExpectedSensor { sensor: s.sensor, model: s.model.clone(), taxels: s.taxels() })
                .collect(),
        }
    }

    /// Checks what serde's types cannot; errors name the setting.
    pub fn validate(&self) -> Result<(), XelaConfigError> {
        let positive = |field: &'static str, ok: bool, value: f64| {
            if ok { Ok(()) } else { Err(XelaConfigError::OutOfRange { field, value }) }
        };
        positive("rate_hz", self.rate_hz.is_finite() && self.rate_hz > 0.0, self.rate_hz)?;
        positive("timeout_ms", self.timeout_ms > 0, self.timeout_ms as f64)?;
        positive("connect_timeout_ms", self.connect_timeout_ms > 0, self.connect_timeout_ms as f64)?;
        let r = &self.reconnect;
        positive(
            "reconnect.max_backoff_ms",
            r.max_backoff_ms >= r.initial_backoff_ms,
            r.max_backoff_ms as f64,
        )?;
        if let Some(s) = self.sensors.iter().find(|s| s.sensor == 0) {
            return Err(XelaConfigError::SensorZero { name: s.name.clone() });
        }
        let e = &self.emulator;
        for (field, v) in
            [("emulator.disconnect_after_s", e.disconnect_after_s), ("emulator.down_for_s", e.down_for_s)]
        {
            if let Some(v) = v {
                positive(field, v.is_finite() && v >= 0.0, v)?;
            }
        }
        validate_sensors(&self.hw_sensors(), self.fingers.as_ref(), usize::MAX)?;
        Ok(())
    }
}

/// A `xela_ws` table with values that cannot work.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum XelaConfigError {
    /// A number outside its range.
    #[error("hw.tactile.{field} = {value} is out of range")]
    OutOfRange {
        /// The setting under `hw.tactile`.
        field: &'static str,
        /// Its value.
        value: f64,
    },
    /// A sensor numbered 0 (the server numbers sensors from 1).
    #[error("hw.tactile.sensors `{name}` has sensor = 0: xela_server numbers its sensors from 1")]
    SensorZero {
        /// The sensor.
        name: String,
    },
    /// A ROS 2 topic name that is not absolute (`kind = "ros2"`).
    #[error("hw.tactile.topic = {topic:?} is not an absolute ROS 2 topic name (like \"/xServTopic\")")]
    Topic {
        /// The topic.
        topic: String,
    },
    /// Sensors or finger readings that do not describe scans.
    #[error(transparent)]
    Sensors(#[from] SensorConfigError),
}
