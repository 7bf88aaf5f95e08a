//! `kind = "ros2"`: the `[hw.tactile]` table of XELA sensors read from
//! XELA's ROS 2 server `xela_server_ros2` (its `SensStream` messages on
//! `/xServTopic`, see `docs/protocols.md` and `docs/ros2.md`). The DDS
//! subscriber itself is `slidetrack_ros2::xela`; `experiment` opens it.
//!
//! ```toml
//! [hw.tactile]
//! kind = "ros2"
//! topic = "/xServTopic"          # the server's topic
//! domain_id = 0                  # absent: ROS_DOMAIN_ID, else 0
//! rate_hz = 100.0                # nominal, recorded in the layout
//! [[hw.tactile.sensors]]         # the sensor_pos values to take, in layout order
//! name = "left"
//! sensor = 1                     # its sensor_pos (xela_server's sensor number)
//! finger = "thumb"
//! model = "uSPa44"
//! rows = 4
//! cols = 4
//! ```

use serde::{Deserialize, Serialize};
use slidetrack_core::{FingerReading, PerFinger, TactileInfo};

use crate::sensors::{HwSensor, tactile_info, validate_sensors};
use crate::xela_ws::config::{XelaConfigError, XelaSensor, default_xela_sensors};

/// The topic `xela_server_ros2` publishes (`xServTopic` of its node, at the root namespace).
pub const DEFAULT_TOPIC: &str = "/xServTopic";

/// Sensors read from `xela_server_ros2` over ROS 2 (DDS).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct XelaRos2TactileConfig {
    /// The ROS 2 topic of `xela_server_ros2/msg/SensStream` messages.
    pub topic: String,
    /// The DDS domain id; absent: `ROS_DOMAIN_ID`, else 0.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub domain_id: Option<u32>,
    /// Nominal scan rate (Hz), recorded in the taxel layout (the server's
    /// rate is set in its xServ.ini).
    pub rate_hz: f64,
    /// Longest wait for a scan once streaming (ms).
    pub timeout_ms: u64,
    /// Longest wait for the first scan, DDS discovery included (ms).
    pub startup_timeout_ms: u64,
    /// The sensors to take, by `sensor_pos` (`sensor`), in layout order;
    /// every taxel of each is kept. Sensors the server sends that are not
    /// listed are ignored.
    pub sensors: Vec<XelaSensor>,
    /// What each finger's reading is; without it, taxel 0 of the sensor
    /// whose `finger` names the finger.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fingers: Option<PerFinger<FingerReading>>,
}

impl Default for XelaRos2TactileConfig {
    fn default() -> Self {
        XelaRos2TactileConfig {
            topic: DEFAULT_TOPIC.into(),
            domain_id: None,
            rate_hz: 100.0,
            timeout_ms: 200,
            startup_timeout_ms: 10_000,
            sensors: default_xela_sensors(),
            fingers: None,
        }
    }
}

impl XelaRos2TactileConfig {
    /// The sensors as the other backends' table.
    pub fn hw_sensors(&self) -> Vec<HwSensor> {
        self.sensors.iter().map(XelaSensor::hw_sensor).collect()
    }

    /// What the source is: its layout and finger readings.
    pub fn info(&self, device: &str) -> TactileInfo {
        tactile_info(device, self.rate_hz, &self.hw_sensors(), self.fingers.as_ref())
    }

    /// Checks what serde's types cannot; errors name the setting.
    pub fn validate(&self) -> Result<(), XelaConfigError> {
        let positive = |field: &'static str, ok: bool, value: f64| {
            if ok { Ok(()) } else { Err(XelaConfigError::OutOfRange { field, value }) }
        };
        positive("rate_hz", self.rate_hz.is_finite() && self.rate_hz > 0.0, self.rate_hz)?;
        positive("timeout_ms", self.timeout_ms > 0, self.timeout_ms as f64)?;
        positive("startup_timeout_ms", self.startup_timeout_ms > 0, self.startup_timeout_ms as f64)?;
        let topic_ok = self.topic.starts_with('/') && self.topic.len() > 1 && !self.topic.contains(' ');
        if !topic_ok {
            return Err(XelaConfigError::Topic { topic: self.topic.clone() });
        }
        if let Some(d) = self.domain_id {
            positive("domain_id", d <= 232, f64::from(d))?;
        }
        if let Some(s) = self.sensors.iter().find(|s| s.sensor == 0) {
            return Err(XelaConfigError::SensorZero { name: s.name.clone() });
        }
        if let Some(s) = self.sensors.iter().find(|s| s.sensor > u32::from(u8::MAX)) {
            positive("sensors.sensor", false, f64::from(s.sensor))?;
        }
        validate_sensors(&self.hw_sensors(), self.fingers.as_ref(), usize::MAX)?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<XelaRos2TactileConfig, String> {
        let cfg: XelaRos2TactileConfig =
            slidetrack_core::parse_toml(text, "rig.toml").map_err(|e| e.to_string())?;
        cfg.validate().map_err(|e| e.to_string())?;
        Ok(cfg)
    }

    #[test]
    fn defaults_are_the_servers_topic_and_three_patches() {
        let cfg = parse("").unwrap();
        assert_eq!(cfg.topic, "/xServTopic");
        assert_eq!(cfg.domain_id, None);
        assert_eq!(cfg.sensors.iter().map(|s| s.sensor).collect::<Vec<_>>(), [1, 2, 3]);
        assert_eq!(cfg.info("ros2").layout.taxel_count(), 48);
    }

    #[test]
    fn bad_settings_name_the_field() {
        assert!(parse("topic = \"xServTopic\"").unwrap_err().contains("hw.tactile.topic"));
        assert!(parse("domain_id = 233").unwrap_err().contains("hw.tactile.domain_id = 233"));
        let big = "[[sensors]]\nname = \"a\"\nsensor = 256\nfinger = \"thumb\"\nmodel = \"uSPa44\"\nrows = 4\ncols = 4";
        assert!(parse(big).unwrap_err().contains("hw.tactile.sensors.sensor = 256"));
        assert!(parse("timeout_ms = 0").unwrap_err().contains("timeout_ms"));
        assert!(parse("port = 3").is_err(), "unknown fields are refused");
    }
}
