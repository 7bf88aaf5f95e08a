//! What labelling reads from a session, in one pass over the file: the
//! tactile scan times and normal loads, the marker detections, the
//! simulator's truth, the protocol's cycles and release, the rig
//! configuration. The sliding ground truth ([`crate::label`]) and the
//! motion in the hand ([`crate::in_hand`]) both start from it.

use std::path::Path;

use slidetrack_core::{Phase, TimeNs};
use slidetrack_session::{
    ArucoDetection, ChannelMessage, MessageReader, ProtocolEvent, ReadOptions, SESSION_METADATA,
    SessionError, SessionInfo, SimTruth, TactileRaw, TactileZeroed,
};

/// What labelling needs from a session.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SessionInputs {
    /// `/tactile/raw` log times.
    pub scans: Vec<TimeNs>,
    /// `/aruco/detections`, `None` when the session has no such channel.
    pub detections: Option<Vec<(TimeNs, ArucoDetection)>>,
    /// `/sim/truth`, empty on real sessions.
    pub truth: Vec<(TimeNs, SimTruth)>,
    /// When the hand released the object (or the trial aborted), from `/protocol/events`.
    pub release: Option<TimeNs>,
    /// The `rig_config` metadata (TOML), if any.
    pub rig_config: Option<String>,
    /// The normal load at every `/tactile/zeroed` scan: the sum of every
    /// taxel's baseline-subtracted z (counts).
    pub loads: Vec<(TimeNs, f64)>,
    /// When the sliding cycles began, from `/protocol/events`.
    pub cycles: Option<TimeNs>,
}

/// Reads what labelling needs in one pass over the file.
pub fn read_inputs(path: &Path, options: ReadOptions) -> Result<SessionInputs, SessionError> {
    let info = SessionInfo::read(path, options)?;
    let rig_config = info.metadata.get(SESSION_METADATA).and_then(|m| m.get("rig_config")).cloned();
    let topics = [
        TactileRaw::TOPIC,
        ArucoDetection::TOPIC,
        SimTruth::TOPIC,
        ProtocolEvent::TOPIC,
        TactileZeroed::TOPIC,
    ];
    let mut inputs = SessionInputs { rig_config, ..SessionInputs::default() };
    let mut detections = Vec::new();
    let mut reader = MessageReader::open(path, &topics, options)?;
    for message in reader.by_ref() {
        let m = message?;
        let decode = |e| SessionError::Decode {
            path: path.to_path_buf(),
            topic: m.topic().to_string(),
            log_time: m.log_time,
            source: e,
        };
        match m.topic() {
            TactileRaw::TOPIC => inputs.scans.push(m.log_time),
            ArucoDetection::TOPIC => {
                detections.push((m.log_time, serde_json::from_slice(&m.data).map_err(decode)?))
            }
            SimTruth::TOPIC => {
                inputs.truth.push((m.log_time, serde_json::from_slice(&m.data).map_err(decode)?))
            }
            TactileZeroed::TOPIC => {
                let z: TactileZeroed = serde_json::from_slice(&m.data).map_err(decode)?;
                let load = z.sensors.iter().flat_map(|s| &s.taxels).map(|t| t.z).sum();
                inputs.loads.push((m.log_time, load));
            }
            _ => {
                let event: ProtocolEvent = serde_json::from_slice(&m.data).map_err(decode)?;
                if inputs.release.is_none() && event.ends_cycles() {
                    inputs.release = Some(m.log_time);
                }
                if inputs.cycles.is_none() && event.phase == Phase::Cycles && !event.abort {
                    inputs.cycles = Some(m.log_time);
                }
            }
        }
    }
    if reader.channels().any(|c| c.topic == ArucoDetection::TOPIC) {
        inputs.detections = Some(detections);
    }
    Ok(inputs)
}
