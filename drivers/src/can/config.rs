//! The `[hw.tactile]` table of `kind = "can"`: the transport (SocketCAN or
//! an SLCAN adapter on a serial port), the layout (legacy ids or an explicit
//! map), the payload format, command frames and scan mode.
//!
//! ```toml
//! [hw.tactile]
//! kind = "can"
//! interface = "can0"                 # SocketCAN (the default transport)
//! # or an SLCAN adapter on a serial port, without slcand:
//! slcan = { port = "/dev/ttyUSB0", bitrate = 1000000 }   # port = "emulated": the pty emulator
//! rate_hz = 100
//! scan_mode = "complete"             # or "latest" (latest value per taxel at rate_hz)
//! stop = { id = 0x201, data = [0] }  # optional, sent when the source closes
//! [hw.tactile.payload]               # default: big-endian x, y, z at bytes 1, 3, 5, no validity byte
//! byte_order = "big"
//! x = 1
//! y = 3
//! z = 5
//! [[hw.tactile.map]]                 # an explicit id map instead of the legacy ids
//! sensor = "thumb"
//! first_id = 0x300                   # taxels 0.. of `thumb` at 0x300..
//! ```

use serde::{Deserialize, Serialize};
use slidetrack_core::{FingerReading, PerFinger};

use crate::can::layout::{
    self, CanMapError, CommandFrame, IdKey, MapEntry, PayloadFormat, ResolvedLayout, ScanMode,
};
use crate::can::protocol::{START_COMMAND, XelaCanLayout};
use crate::can_hand::protocol::HandCanIds;
use crate::config::error::{HwConfigError, IdCollision, check};
use crate::sensors::validate_sensors;
use crate::sensors::{HwSensor, default_sensors};
use crate::slcan::config::SlcanTransport;

/// A uSkin-style board (or several) on CAN.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CanTactileConfig {
    /// SocketCAN interface (`can0`, `vcan0`, `slcan0`), unless `slcan` is given.
    pub interface: String,
    /// An SLCAN adapter on a serial port instead of SocketCAN.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub slcan: Option<SlcanTransport>,
    /// Legacy layout: board id (the start command goes to `start_base_id | board`).
    pub board: u8,
    /// Legacy layout: base id of the start command.
    pub start_base_id: u32,
    /// Legacy layout: id of board taxel 0's frames.
    pub taxel_base_id: u32,
    /// Legacy layout: taxels on the board (all modules together).
    pub taxels: u16,
    /// Legacy layout: taxels per module: taxel `t` of a sensor on module `m`
    /// is board taxel `m * taxels_per_module + t`.
    pub taxels_per_module: u16,
    /// An explicit id map; when given, the legacy ids and start command are
    /// not used.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub map: Vec<MapEntry>,
    /// How a taxel frame's payload holds x, y and z.
    pub payload: PayloadFormat,
    /// A frame sent after opening the bus; replaces the legacy start
    /// command (`start_base_id | board`, `[7, 0]`), which is sent when no
    /// `map` and no `start` is given.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub start: Option<CommandFrame>,
    /// A frame sent when the source closes (the trial ends, or the program
    /// stops); none by default.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub stop: Option<CommandFrame>,
    /// A standard id whose frames mark the start of a scan (complete mode).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub scan_start_id: Option<u32>,
    /// How frames become scans.
    pub scan_mode: ScanMode,
    /// Nominal scan rate (Hz): recorded in the layout; the emission rate
    /// of `scan_mode = "latest"`.
    pub rate_hz: f64,
    /// Longest wait for a scan once streaming (ms).
    pub timeout_ms: u64,
    /// Longest wait for the first scan after the start command (ms).
    pub startup_timeout_ms: u64,
    /// The sensors: which modules are read, their layout and finger.
    pub sensors: Vec<HwSensor>,
    /// What each finger's reading is (a taxel of a sensor, or its mean);
    /// without it, taxel 0 of the sensor whose `finger` names the finger
    /// ([`crate::sensors::finger_readings`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fingers: Option<PerFinger<FingerReading>>,
}

impl Default for CanTactileConfig {
    fn default() -> Self {
        let layout = XelaCanLayout::default();
        CanTactileConfig {
            interface: "can0".into(),
            slcan: None,
            board: layout.board,
            start_base_id: layout.start_base_id,
            taxel_base_id: layout.taxel_base_id,
            taxels: 48,
            taxels_per_module: 16,
            map: Vec::new(),
            payload: PayloadFormat::default(),
            start: None,
            stop: None,
            scan_start_id: None,
            scan_mode: ScanMode::Complete,
            rate_hz: 100.0,
            timeout_ms: 50,
            startup_timeout_ms: 2000,
            sensors: default_sensors(4, 4),
            fingers: None,
        }
    }
}

impl CanTactileConfig {
    /// The legacy board layout (ids of the legacy scheme).
    pub fn legacy_layout(&self) -> XelaCanLayout {
        XelaCanLayout {
            board: self.board,
            start_base_id: self.start_base_id,
            taxel_base_id: self.taxel_base_id,
            taxels: self.taxels,
        }
    }

    /// The layout resolved against the sensors: slots, ids, payload,
    /// command frames, scan mode.
    pub fn layout(&self) -> Result<ResolvedLayout, CanMapError> {
        let assignments = if self.map.is_empty() {
            layout::legacy_assignments(&self.sensors, self.taxel_base_id, self.taxels_per_module)
        } else {
            layout::map_assignments(&self.sensors, &self.map)?
        };
        let legacy_start = CommandFrame {
            id: self.start_base_id | u32::from(self.board),
            extended: false,
            data: START_COMMAND.to_vec(),
        };
        let start = match (&self.start, self.map.is_empty()) {
            (Some(s), _) => vec![(s, "hw.tactile.start".to_string())],
            (None, true) => vec![(&legacy_start, "hw.tactile.start_base_id | board".to_string())],
            (None, false) => vec![],
        };
        let stop: Vec<_> = self.stop.iter().map(|s| (s, "hw.tactile.stop".to_string())).collect();
        let mut layout =
            layout::resolve(&self.sensors, assignments, self.payload, &start, &stop, self.scan_mode)?;
        if let Some(id) = self.scan_start_id {
            if id > crate::can::protocol::MAX_STANDARD_ID {
                return Err(CanMapError::IdRange { key: "hw.tactile.scan_start_id".into(), id, bits: 11 });
            }
            layout.scan_start_id = Some((id, false));
        }
        Ok(layout)
    }

    /// The device name for messages and the layout: the interface or the
    /// SLCAN port.
    pub fn device(&self) -> &str {
        self.slcan.as_ref().map_or(&self.interface, |s| &s.port)
    }

    /// A tactile id that the hand on `hand_interface` also uses, when both
    /// are on the same SocketCAN interface.
    pub fn collision_with_hand(&self, hand_interface: &str, hand: &HandCanIds) -> Option<IdCollision> {
        if self.slcan.is_some() || self.interface != hand_interface {
            return None;
        }
        let layout = self.layout().ok()?;
        let hand_ids = [
            (hand.setpoint_id, "hw.hand.setpoint_id"),
            (hand.heartbeat_id, "hw.hand.heartbeat_id"),
            (hand.release_id, "hw.hand.release_id"),
        ];
        layout.used_ids().find_map(|((id, extended), key): (IdKey, &str)| {
            let (_, hand_key) = hand_ids.iter().find(|(h, _)| !extended && *h == id)?;
            Some(IdCollision {
                tactile_key: key.to_string(),
                hand_key: (*hand_key).to_string(),
                id,
                interface: self.interface.clone(),
            })
        })
    }

    /// The checks that serde's types cannot make.
    pub fn validate(&self) -> Result<(), HwConfigError> {
        let c = self;
        if c.map.is_empty() {
            c.legacy_layout().validate()?;
        }
        c.layout()?;
        if let Some(s) = &c.slcan {
            crate::slcan::protocol::bitrate_code(s.bitrate)
                .map_err(|e| HwConfigError::Can(format!("hw.tactile.slcan.bitrate: {e}")))?;
            if let Some(t) = s.unplug_after_s {
                check("tactile.slcan.unplug_after_s", t, t.is_finite() && t >= 0.0, ">= 0 s")?;
            }
        }
        check("tactile.rate_hz", c.rate_hz, c.rate_hz.is_finite() && c.rate_hz > 0.0, "> 0 Hz")?;
        check("tactile.timeout_ms", c.timeout_ms as f64, c.timeout_ms > 0, "> 0 ms")?;
        let per = f64::from(c.taxels_per_module);
        check("tactile.taxels_per_module", per, c.taxels_per_module > 0, ">= 1")?;
        // With an explicit map, modules and taxels_per_module are not used.
        let per_module = if c.map.is_empty() { usize::from(c.taxels_per_module) } else { usize::MAX };
        validate_sensors(&c.sensors, c.fingers.as_ref(), per_module)?;
        let per = usize::from(c.taxels_per_module);
        for x in c.sensors.iter().filter(|_| c.map.is_empty()) {
            let end = x.module as usize * per + x.taxels();
            if end > usize::from(c.taxels) {
                let (name, module, taxels) = (x.name.clone(), x.module, c.taxels);
                return Err(HwConfigError::BeyondBoard { name, module, end, taxels });
            }
        }
        Ok(())
    }
}
