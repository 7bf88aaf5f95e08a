//! `[hw.hand] kind = "robotiq"`: a Robotiq 2F-85, 2F-140 or Hand-E on
//! Modbus RTU.
//!
//! ```toml
//! [hw.hand]
//! kind = "robotiq"
//! port = "/dev/ttyUSB0"   # or "emulated": the kinematic gripper behind a pseudo-terminal
//! model = "2f85"          # "2f140", "hand-e"
//! baud = 115200
//! device_id = 9
//! ```

use serde::{Deserialize, Serialize};
use slidetrack_core::GripperSpec;
use thiserror::Error;

/// The gripper models, each with the stroke, speeds and forces of its
/// manual's specifications.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum RobotiqModel {
    /// 2F-85: 85 mm stroke, 20-150 mm/s, 20-235 N.
    #[default]
    #[serde(rename = "2f85")]
    TwoF85,
    /// 2F-140: 140 mm stroke, 30-250 mm/s, 10-125 N.
    #[serde(rename = "2f140")]
    TwoF140,
    /// Hand-E: 50 mm stroke, 20-150 mm/s, 20-185 N.
    #[serde(rename = "hand-e")]
    HandE,
}

impl RobotiqModel {
    /// The model's name as the config and the CLI spell it.
    pub fn name(self) -> &'static str {
        match self {
            RobotiqModel::TwoF85 => "2f85",
            RobotiqModel::TwoF140 => "2f140",
            RobotiqModel::HandE => "hand-e",
        }
    }

    /// From its name (`2f85`, `2f140`, `hand-e`).
    pub fn from_name(name: &str) -> Option<RobotiqModel> {
        [RobotiqModel::TwoF85, RobotiqModel::TwoF140, RobotiqModel::HandE]
            .into_iter()
            .find(|m| m.name() == name)
    }

    /// What the gripper accepts: 8-bit requests over the model's ranges.
    pub fn spec(self) -> GripperSpec {
        match self {
            RobotiqModel::TwoF85 => GripperSpec::robotiq_2f85(),
            RobotiqModel::TwoF140 => GripperSpec {
                max_steps: 255,
                stroke_m: 0.140,
                speed_range_mps: (0.03, 0.25),
                force_range_n: (10.0, 125.0),
            },
            RobotiqModel::HandE => GripperSpec {
                max_steps: 255,
                stroke_m: 0.050,
                speed_range_mps: (0.02, 0.15),
                force_range_n: (20.0, 185.0),
            },
        }
    }
}

/// A Robotiq gripper on a serial port.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RobotiqConfig {
    /// Device path of the USB-RS485 adapter (`/dev/ttyUSB0`), or `emulated`.
    pub port: String,
    /// The model.
    pub model: RobotiqModel,
    /// Baud rate (the gripper's default is 115200, 8N1).
    pub baud: u32,
    /// Modbus device id (the gripper's default is 9).
    pub device_id: u8,
    /// Longest wait for one response (ms).
    pub response_timeout_ms: u64,
    /// Longest time without a valid response before the gripper counts as
    /// gone (ms).
    pub link_timeout_ms: u64,
    /// Longest wait for the activation to complete (`gSTA = 3`) (ms).
    pub activation_timeout_ms: u64,
    /// Least time between two transactions (ms); 0: as fast as the link answers.
    pub poll_period_ms: u64,
    /// Speed of the release and of position-only requests
    /// (`RobotiqGripper::position_request`), 0-255.
    pub speed: u8,
    /// Force of the release and of position-only requests, 0-255.
    pub force: u8,
    /// Send a position request and read the status in one FC23
    /// transaction; false: an FC16 write, then an FC03 read.
    pub read_write_in_one: bool,
    /// The emulated gripper (only with `port = "emulated"`).
    pub emulator: RobotiqEmulatorConfig,
}

impl Default for RobotiqConfig {
    fn default() -> Self {
        RobotiqConfig {
            port: "/dev/ttyUSB0".into(),
            model: RobotiqModel::TwoF85,
            baud: 115_200,
            device_id: 9,
            response_timeout_ms: 100,
            link_timeout_ms: 500,
            activation_timeout_ms: 10_000,
            poll_period_ms: 0,
            speed: 128,
            force: 64,
            read_write_in_one: true,
            emulator: RobotiqEmulatorConfig::default(),
        }
    }
}

/// The emulated gripper's object and faults (with `port = "emulated"`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RobotiqEmulatorConfig {
    /// Opening at which the fingers meet an object (mm); none: no object.
    pub object_width_mm: Option<f64>,
    /// Time from `rACT = 1` to `gSTA = 3` (s).
    pub activation_s: f64,
    /// Report this `gFLT` code `fault_after_s` after the activation.
    pub fault_code: Option<u8>,
    /// When the fault appears (s after the activation completed).
    pub fault_after_s: f64,
    /// Stop answering (port left open) this long after the activation (s).
    pub silent_after_s: Option<f64>,
    /// Close the pseudo-terminal this long after the activation (s).
    pub unplug_after_s: Option<f64>,
}

impl Default for RobotiqEmulatorConfig {
    fn default() -> Self {
        RobotiqEmulatorConfig {
            object_width_mm: None,
            activation_s: 1.5,
            fault_code: None,
            fault_after_s: 0.0,
            silent_after_s: None,
            unplug_after_s: None,
        }
    }
}

/// A `kind = "robotiq"` table that cannot work.
#[derive(Clone, Debug, Error, PartialEq)]
#[error("hw.hand.{field} = {value} is out of range ({expected})")]
pub struct RobotiqConfigError {
    /// The setting, as in the file.
    pub field: &'static str,
    /// Its value.
    pub value: f64,
    /// The valid range, in words.
    pub expected: &'static str,
}

impl RobotiqConfig {
    /// Checks what serde's types cannot.
    pub fn validate(&self) -> Result<(), RobotiqConfigError> {
        let check = |field, value: f64, ok: bool, expected| {
            if ok { Ok(()) } else { Err(RobotiqConfigError { field, value, expected }) }
        };
        check("baud", f64::from(self.baud), (1200..=4_000_000).contains(&self.baud), "1200..=4000000")?;
        let id = f64::from(self.device_id);
        check("device_id", id, (1..=247).contains(&self.device_id), "1..=247 (Modbus unicast ids)")?;
        let ms = |v: u64| v as f64;
        check("response_timeout_ms", ms(self.response_timeout_ms), self.response_timeout_ms > 0, "> 0 ms")?;
        let link_ok = self.link_timeout_ms >= self.response_timeout_ms;
        check("link_timeout_ms", ms(self.link_timeout_ms), link_ok, ">= response_timeout_ms")?;
        check(
            "activation_timeout_ms",
            ms(self.activation_timeout_ms),
            self.activation_timeout_ms > 0,
            "> 0 ms",
        )?;
        check("poll_period_ms", ms(self.poll_period_ms), self.poll_period_ms <= 1000, "0..=1000 ms")?;
        let e = &self.emulator;
        let stroke_mm = self.model.spec().stroke_m * 1000.0;
        if let Some(w) = e.object_width_mm {
            let ok = w.is_finite() && (0.0..stroke_mm).contains(&w);
            check("emulator.object_width_mm", w, ok, "0 mm up to the model's stroke")?;
        }
        let times = [
            ("emulator.activation_s", Some(e.activation_s)),
            ("emulator.fault_after_s", Some(e.fault_after_s)),
            ("emulator.silent_after_s", e.silent_after_s),
            ("emulator.unplug_after_s", e.unplug_after_s),
        ];
        for (field, t) in times {
            if let Some(t) = t {
                check(field, t, t.is_finite() && t >= 0.0, ">= 0 s")?;
            }
        }
        if let Some(code) = e.fault_code {
            check(
                "emulator.fault_code",
                f64::from(code),
                (1..=15).contains(&code),
                "1..=15 (gFLT is 4 bits)",
            )?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_minimal_table_gets_the_documented_defaults() {
        let cfg: RobotiqConfig = toml::from_str("port = \"/dev/ttyUSB1\"\nmodel = \"hand-e\"").unwrap();
        assert_eq!((cfg.baud, cfg.device_id, cfg.model), (115_200, 9, RobotiqModel::HandE));
        assert!((cfg.model.spec().stroke_m - 0.05).abs() < 1e-12);
        cfg.validate().unwrap();
    }

    #[test]
    fn bad_values_name_their_field() {
        let bad =
            |text: &str| toml::from_str::<RobotiqConfig>(text).unwrap().validate().unwrap_err().to_string();
        assert_eq!(
            bad("device_id = 0"),
            "hw.hand.device_id = 0 is out of range (1..=247 (Modbus unicast ids))"
        );
        assert!(
            bad("[emulator]\nobject_width_mm = 90.0").starts_with("hw.hand.emulator.object_width_mm = 90")
        );
        assert!(bad("link_timeout_ms = 10").starts_with("hw.hand.link_timeout_ms"));
        let unknown = toml::from_str::<RobotiqConfig>("model = \"3f\"").unwrap_err().to_string();
        assert!(unknown.contains("2f85"), "{unknown}");
    }
}
