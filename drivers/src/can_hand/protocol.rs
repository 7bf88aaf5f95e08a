//! The hand actuator's CAN frames (see `docs/protocols.md`), without I/O.
//!
//! | frame     | id (default) | DLC | data |
//! |-----------|--------------|-----|------|
//! | set-point | `0x300`      | 7   | counter u8, then thumb, index, middle proximal-joint voltage as i16 big-endian millivolts |
//! | heartbeat | `0x301`      | 2   | counter u8, state u8 (0 idle, 1 commanding, 2 released) |
//! | release   | `0x302`      | 2   | `0x52 0x4C` ("RL") |
//!
//! The hand's firmware holds the last set-point, opens the hand on a release
//! frame, and opens it by itself when heartbeats stop for three periods.

use serde::{Deserialize, Serialize};
use slidetrack_core::FingerVolts;
use thiserror::Error;

use crate::can::protocol::{CanFrame, MAX_STANDARD_ID};

/// Data of the release frame.
pub const RELEASE_MAGIC: [u8; 2] = [0x52, 0x4C];
/// Millivolts per volt in the set-point frame.
const MV_PER_V: f64 = 1000.0;

/// The identifiers of the hand's frames.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct HandCanIds {
    /// Id of the set-point frame.
    pub setpoint_id: u32,
    /// Id of the heartbeat frame.
    pub heartbeat_id: u32,
    /// Id of the release frame.
    pub release_id: u32,
}

impl Default for HandCanIds {
    fn default() -> Self {
        HandCanIds { setpoint_id: 0x300, heartbeat_id: 0x301, release_id: 0x302 }
    }
}

/// What the host tells the hand through its heartbeat.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum HandState {
    /// Connected, no set-point sent yet.
    Idle = 0,
    /// Set-points are being sent.
    Commanding = 1,
    /// The hand was released.
    Released = 2,
}

/// A decoded hand frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum HandMessage {
    /// Voltages for the proximal joints.
    Setpoint {
        /// Wrapping frame counter.
        counter: u8,
        /// `[thumb, index, middle]` (V), at 1 mV resolution.
        volts: FingerVolts,
    },
    /// The host is alive.
    Heartbeat {
        /// Wrapping frame counter.
        counter: u8,
        /// The host's state.
        state: HandState,
    },
    /// Open the hand.
    Release,
}

/// A hand frame that does not decode.
#[derive(Clone, Debug, Error, PartialEq, Eq)]
pub enum HandFrameError {
    /// The data length does not match the frame kind.
    #[error("hand {kind} frame 0x{id:X} has {len} data bytes, expected {expected}")]
    Length {
        /// Which frame.
        kind: &'static str,
        /// Its id.
        id: u32,
        /// Bytes received.
        len: usize,
        /// Bytes the layout has.
        expected: usize,
    },
    /// A heartbeat state or release payload that the layout does not define.
    #[error("hand {kind} frame 0x{id:X} carries unknown data {data:02X?}")]
    BadData {
        /// Which frame.
        kind: &'static str,
        /// Its id.
        id: u32,
        /// The data.
        data: Vec<u8>,
    },
    /// An identifier beyond the 11-bit range, or two frames sharing an id.
    #[error("hand CAN ids must be distinct standard ids (<= 0x7FF): {ids:X?}")]
    BadIds {
        /// `[setpoint, heartbeat, release]`.
        ids: [u32; 3],
    },
}

impl HandCanIds {
    /// Checks that the ids are distinct standard ids.
    pub fn validate(&self) -> Result<(), HandFrameError> {
        let ids = [self.setpoint_id, self.heartbeat_id, self.release_id];
        let distinct = ids[0] != ids[1] && ids[0] != ids[2] && ids[1] != ids[2];
        if !distinct || ids.iter().any(|&id| id > MAX_STANDARD_ID) {
            return Err(HandFrameError::BadIds { ids });
        }
        Ok(())
    }

    /// The set-point frame for `volts` (V, `[thumb, index, middle]`); values
    /// are rounded to millivolts and clamped to the i16 range, NaN sends 0.
    pub fn setpoint(&self, counter: u8, volts: FingerVolts) -> CanFrame {
        let mut data = [0u8; 7];
        data[0] = counter;
        for (k, v) in volts.iter().enumerate() {
            let mv = if v.is_nan() { 0.0 } else { (v * MV_PER_V).round() };
            let mv = mv.clamp(f64::from(i16::MIN), f64::from(i16::MAX)) as i16;
            data[1 + 2 * k..3 + 2 * k].copy_from_slice(&mv.to_be_bytes());
        }
        standard(self.setpoint_id, &data)
    }

    /// The heartbeat frame.
    pub fn heartbeat(&self, counter: u8, state: HandState) -> CanFrame {
        standard(self.heartbeat_id, &[counter, state as u8])
    }

    /// The release frame.
    pub fn release(&self) -> CanFrame {
        standard(self.release_id, &RELEASE_MAGIC)
    }

    /// Decodes a frame: `Ok(None)` when it is not one of the hand's ids.
    pub fn decode(&self, frame: &CanFrame) -> Result<Option<HandMessage>, HandFrameError> {
        if frame.extended {
            return Ok(None);
        }
        let data = frame.data();
        let check = |kind: &'static str, expected: usize| {
            if data.len() == expected {
                Ok(())
            } else {
                Err(HandFrameError::Length { kind, id: frame.id, len: data.len(), expected })
            }
        };
        if frame.id == self.setpoint_id {
            check("set-point", 7)?;
            let mv = |i: usize| f64::from(i16::from_be_bytes([data[i], data[i + 1]])) / MV_PER_V;
            return Ok(Some(HandMessage::Setpoint { counter: data[0], volts: [mv(1), mv(3), mv(5)] }));
        }
        if frame.id == self.heartbeat_id {
            check("heartbeat", 2)?;
            let state = match data[1] {
                0 => HandState::Idle,
                1 => HandState::Commanding,
                2 => HandState::Released,
                _ => {
                    let data = data.to_vec();
                    return Err(HandFrameError::BadData { kind: "heartbeat", id: frame.id, data });
                }
            };
            return Ok(Some(HandMessage::Heartbeat { counter: data[0], state }));
        }
        if frame.id == self.release_id {
            check("release", 2)?;
            if data != RELEASE_MAGIC {
                return Err(HandFrameError::BadData { kind: "release", id: frame.id, data: data.to_vec() });
            }
            return Ok(Some(HandMessage::Release));
        }
        Ok(None)
    }
}

/// A standard frame; ids are validated before use (out-of-range ids are masked).
fn standard(id: u32, data: &[u8]) -> CanFrame {
    CanFrame::standard_masked(id, data)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_round_trip_through_the_documented_layout() {
        let ids = HandCanIds::default();
        let f = ids.setpoint(7, [1.5, -2.25, 0.0004]);
        assert_eq!((f.id, f.data()), (0x300, &[7, 0x05, 0xDC, 0xF7, 0x36, 0x00, 0x00][..]));
        assert_eq!(ids.decode(&f), Ok(Some(HandMessage::Setpoint { counter: 7, volts: [1.5, -2.25, 0.0] })));
        let h = ids.heartbeat(255, HandState::Released);
        assert_eq!((h.id, h.data()), (0x301, &[255, 2][..]));
        assert_eq!(
            ids.decode(&h),
            Ok(Some(HandMessage::Heartbeat { counter: 255, state: HandState::Released }))
        );
        let r = ids.release();
        assert_eq!((r.id, r.data()), (0x302, &RELEASE_MAGIC[..]));
        assert_eq!(ids.decode(&r), Ok(Some(HandMessage::Release)));
        assert_eq!(ids.decode(&CanFrame::standard(0x710, &[0; 8]).unwrap()), Ok(None));
    }

    #[test]
    fn set_points_saturate_and_never_send_nan() {
        let ids = HandCanIds::default();
        let Ok(Some(HandMessage::Setpoint { volts, .. })) =
            ids.decode(&ids.setpoint(0, [1e9, -1e9, f64::NAN]))
        else {
            panic!("not a set-point")
        };
        assert_eq!(volts, [32.767, -32.768, 0.0]);
    }

    #[test]
    fn malformed_frames_are_typed_errors() {
        let ids = HandCanIds::default();
        let short = CanFrame::standard(0x300, &[1, 2]).unwrap();
        assert!(matches!(ids.decode(&short), Err(HandFrameError::Length { expected: 7, len: 2, .. })));
        let state = CanFrame::standard(0x301, &[0, 9]).unwrap();
        assert!(matches!(ids.decode(&state), Err(HandFrameError::BadData { kind: "heartbeat", .. })));
        let release = CanFrame::standard(0x302, &[0, 0]).unwrap();
        assert!(matches!(ids.decode(&release), Err(HandFrameError::BadData { kind: "release", .. })));
        assert!(HandCanIds { heartbeat_id: 0x300, ..ids }.validate().is_err());
        assert!(HandCanIds { release_id: 0x900, ..ids }.validate().is_err());
        ids.validate().unwrap();
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(
            std::env::var("PROPTEST_CASES").ok().and_then(|s| s.parse().ok()).unwrap_or(256)
        ))]

        /// Any frame decodes to a message, a typed error or nothing; never a panic.
        #[test]
        fn arbitrary_frames_never_panic(
            id in 0x2F0u32..0x310,
            extended: bool,
            data in proptest::collection::vec(proptest::prelude::any::<u8>(), 0..=8),
        ) {
            let frame = CanFrame::new(id, extended, &data).expect("a valid frame");
            let decoded = HandCanIds::default().decode(&frame);
            let ours = !extended && (0x300..=0x302).contains(&id);
            proptest::prop_assert!(ours || decoded == Ok(None));
        }

        /// Set-points within the i16 millivolt range survive the round trip to 0.5 mV.
        #[test]
        fn set_points_round_trip(counter: u8, volts in proptest::array::uniform3(-32.0f64..32.0)) {
            let ids = HandCanIds::default();
            let Ok(Some(HandMessage::Setpoint { counter: c, volts: back })) = ids.decode(&ids.setpoint(counter, volts))
            else {
                return Err(proptest::test_runner::TestCaseError::fail("not a set-point"));
            };
            proptest::prop_assert_eq!(c, counter);
            for (a, b) in volts.iter().zip(back) {
                proptest::prop_assert!((a - b).abs() <= 0.0005 + 1e-12, "{} vs {}", a, b);
            }
        }
    }
}
