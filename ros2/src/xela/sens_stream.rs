//! The messages of XELA's ROS 2 server `xela_server_ros2` (msg/*.msg of
//! github.com/mcsix/xela_server_ros2, commit 3a890cf; see
//! `docs/protocols.md`), decoded from CDR:
//!
//! ```text
//! SensStream:  SensorFull[] sensors
//! SensorFull:  uint32 message, float64 time, string model, uint8 sensor_pos,
//!              Taxel[] taxels, Forces[] forces
//! Taxel:       uint16 x, uint16 y, uint16 z
//! Forces:      float32 x, float32 y, float32 z
//! ```

use super::cdr_read::CdrReader;
use super::error::CdrError;

/// The ROS 2 type of the server's topic.
pub const SENS_STREAM_TYPE: &str = "xela_server_ros2/msg/SensStream";

/// The server's topic (`xServTopic`, in the node's namespace: `/xServTopic`).
pub const SENS_STREAM_TOPIC: &str = "/xServTopic";

/// One `SensStream`: a scan of every sensor the server reads.
#[derive(Clone, Debug, PartialEq)]
pub struct SensStream {
    /// The sensors, in the server's order.
    pub sensors: Vec<SensorFull>,
}

/// One sensor's part of a scan.
#[derive(Clone, Debug, PartialEq)]
pub struct SensorFull {
    /// The websocket message's counter (`message`).
    pub message: u32,
    /// The server's time of the scan (Unix time, s).
    pub time_s: f64,
    /// The model (`uSPa44`).
    pub model: String,
    /// The sensor's number: its key in `xela_server`'s websocket messages (1, 2, ...).
    pub sensor_pos: u8,
    /// Raw counts `[x, y, z]` per taxel, in the server's order (row by row).
    pub taxels: Vec<[u16; 3]>,
    /// Calibrated forces `[x, y, z]` (N) per taxel; empty without calibration.
    pub forces: Vec<[f32; 3]>,
}

/// Padding a publisher may leave after the last field (to a multiple of 4 bytes).
const MAX_END_PADDING: usize = 3;

impl SensStream {
    /// Decodes a CDR body (after the encapsulation header).
    pub fn decode(body: &[u8]) -> Result<SensStream, CdrError> {
        let mut r = CdrReader::new(body);
        // A SensorFull takes at least 4 + 8 + 4 + 1 + 4 + 4 bytes.
        let n = r.seq_len("sensors", 25)?;
        let mut sensors = Vec::with_capacity(n);
        for _ in 0..n {
            sensors.push(sensor(&mut r)?);
        }
        if r.remaining() > MAX_END_PADDING {
            return Err(CdrError::Trailing { extra: r.remaining() });
        }
        Ok(SensStream { sensors })
    }
}

fn sensor(r: &mut CdrReader<'_>) -> Result<SensorFull, CdrError> {
    let message = r.u32("message")?;
    let time_s = r.f64("time")?;
    let model = r.string("model")?;
    let sensor_pos = r.u8("sensor_pos")?;
    let n = r.seq_len("taxels", 6)?;
    let mut taxels = Vec::with_capacity(n);
    for _ in 0..n {
        taxels.push([r.u16("taxels.x")?, r.u16("taxels.y")?, r.u16("taxels.z")?]);
    }
    let n = r.seq_len("forces", 12)?;
    let mut forces = Vec::with_capacity(n);
    for _ in 0..n {
        forces.push([r.f32("forces.x")?, r.f32("forces.y")?, r.f32("forces.z")?]);
    }
    Ok(SensorFull { message, time_s, model, sensor_pos, taxels, forces })
}

#[cfg(test)]
mod tests {
    use slidetrack_session::ros2::CdrWriter;

    use super::*;

    /// A body built byte by byte: one sensor, `uSPa44` at position 2,
    /// two taxels, one force.
    fn hand_built() -> Vec<u8> {
        [
            &[1, 0, 0, 0][..],            // sensors: 1
            &[7, 0, 0, 0],                // message 7 (offset 4)
            &2.5f64.to_le_bytes(),        // time (offset 8, aligned already)
            &[7, 0, 0, 0],                // model: 7 bytes with NUL (offset 16)
            b"uSPa44\0",                  // (offset 20)
            &[2],                         // sensor_pos (offset 27)
            &[2, 0, 0, 0],                // taxels: 2 (offset 28)
            &[1, 0, 2, 0, 3, 0],          // taxel 0 (offset 32)
            &[0xff, 0xff, 0, 0x80, 5, 0], // taxel 1: 65535, 32768, 5
            &[1, 0, 0, 0],                // forces: 1 (offset 44)
            &0.5f32.to_le_bytes(),
            &(-1.0f32).to_le_bytes(),
            &2.0f32.to_le_bytes(),
        ]
        .concat()
    }

    fn expected() -> SensStream {
        SensStream {
            sensors: vec![SensorFull {
                message: 7,
                time_s: 2.5,
                model: "uSPa44".into(),
                sensor_pos: 2,
                taxels: vec![[1, 2, 3], [65535, 32768, 5]],
                forces: vec![[0.5, -1.0, 2.0]],
            }],
        }
    }

    #[test]
    fn a_hand_built_message_decodes_field_by_field() {
        assert_eq!(SensStream::decode(&hand_built()).unwrap(), expected());
        // End padding to 4 bytes, as Fast DDS writes it, is allowed.
        let mut padded = hand_built();
        padded.extend_from_slice(&[0, 0, 0]);
        assert_eq!(SensStream::decode(&padded).unwrap(), expected());
    }

    #[test]
    fn the_project_writer_and_the_decoder_agree_on_alignment() {
        // The second sensor starts unaligned after the first's forces: its
        // `time` must be padded to 8 after the `message`.
        let mut w = CdrWriter::new();
        w.seq_len(2);
        for (pos, taxels) in [(1u8, vec![[10u16, 20, 30]]), (3, vec![[4, 5, 6], [7, 8, 9], [1, 1, 1]])] {
            w.u32(99).f64(1.25).string("uSCu").u8(pos).seq_len(taxels.len());
            for t in &taxels {
                w.u16(t[0]).u16(t[1]).u16(t[2]);
            }
            w.seq_len(0);
        }
        let m = SensStream::decode(&w.finish()[4..]).unwrap();
        assert_eq!(m.sensors.len(), 2);
        assert_eq!(m.sensors[1].sensor_pos, 3);
        assert_eq!(m.sensors[1].taxels, vec![[4, 5, 6], [7, 8, 9], [1, 1, 1]]);
        assert_eq!(m.sensors[1].time_s, 1.25);
        assert!(m.sensors[0].forces.is_empty());
    }

    #[test]
    fn every_truncation_is_a_typed_error() {
        let full = hand_built();
        for len in 0..full.len() {
            let e = SensStream::decode(&full[..len]).expect_err("a truncated message");
            assert!(
                matches!(e, CdrError::Truncated { .. } | CdrError::Length { .. } | CdrError::NoNul { .. }),
                "{len}: {e}"
            );
            assert!(!e.to_string().contains('\n'));
        }
    }

    #[test]
    fn corrupted_counts_strings_and_tails_are_refused() {
        let mut huge = hand_built();
        huge[28..32].copy_from_slice(&u32::MAX.to_le_bytes()); // taxel count
        assert!(matches!(SensStream::decode(&huge), Err(CdrError::Length { field: "taxels", .. })));
        let mut sensors = hand_built();
        sensors[0] = 200;
        assert!(SensStream::decode(&sensors).is_err());
        let mut nul = hand_built();
        nul[26] = b'X'; // the model's NUL
        assert!(matches!(SensStream::decode(&nul), Err(CdrError::NoNul { field: "model" })));
        let mut tail = hand_built();
        tail.extend_from_slice(&[0; 4]);
        assert!(matches!(SensStream::decode(&tail), Err(CdrError::Trailing { extra: 4 })));
        // Every single-byte corruption decodes or fails, never panics.
        let full = hand_built();
        for i in 0..full.len() {
            for v in [0u8, 0x7f, 0xff] {
                let mut c = full.clone();
                c[i] = v;
                let _ = SensStream::decode(&c);
            }
        }
    }
}
