//! The `[hw.hand]` table of `kind = "can"`: the hand's interface, frame ids,
//! heartbeat and voltage limit.

use serde::{Deserialize, Serialize};

use crate::can_hand::protocol::HandCanIds;
use crate::config::error::{HwConfigError, check};

/// The hand on CAN.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CanHandConfig {
    /// SocketCAN interface.
    pub interface: String,
    /// Id of the set-point frame.
    pub setpoint_id: u32,
    /// Id of the heartbeat frame.
    pub heartbeat_id: u32,
    /// Id of the release frame.
    pub release_id: u32,
    /// Heartbeat period (ms); the hand opens by itself after three missed.
    pub heartbeat_ms: u64,
    /// Largest voltage magnitude sent (V).
    pub max_volts: f64,
}

impl Default for CanHandConfig {
    fn default() -> Self {
        let ids = HandCanIds::default();
        CanHandConfig {
            interface: "can0".into(),
            setpoint_id: ids.setpoint_id,
            heartbeat_id: ids.heartbeat_id,
            release_id: ids.release_id,
            heartbeat_ms: 20,
            max_volts: 10.0,
        }
    }
}

impl CanHandConfig {
    /// The frame ids.
    pub fn ids(&self) -> HandCanIds {
        HandCanIds {
            setpoint_id: self.setpoint_id,
            heartbeat_id: self.heartbeat_id,
            release_id: self.release_id,
        }
    }
}

impl CanHandConfig {
    /// The checks that serde's types cannot make.
    pub fn validate(&self) -> Result<(), HwConfigError> {
        let h = self;
        h.ids().validate()?;
        check("hand.max_volts", h.max_volts, h.max_volts.is_finite() && h.max_volts > 0.0, "> 0 V")?;
        let hb = h.heartbeat_ms as f64;
        check("hand.heartbeat_ms", hb, (1..=1000).contains(&h.heartbeat_ms), "1..=1000 ms")?;
        Ok(())
    }
}
