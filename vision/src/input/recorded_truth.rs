//! [`RecordedTruth`]: the ground truth of a replayed simulated session
//! (`/sim/object`, `/rgbd/mask`), looked up by recording time as the replay
//! goes, so that a live run on a recorded stand-in can use the truth-based
//! measurement sources and be scored.

use std::iter::Peekable;
use std::path::{Path, PathBuf};

use slidetrack_core::{ObjectTruth as SimObjectTruth, TimeNs};
use slidetrack_estimators::roft::Mask;
use slidetrack_session::{ChannelMessage, MessageReader, ObjectTruth, ReadOptions, RgbdMask};

use crate::VisionError;

/// The truth of a session, read forward in time with bounded memory.
pub struct RecordedTruth {
    path: PathBuf,
    reader: Peekable<MessageReader>,
}

impl RecordedTruth {
    /// Opens the truth channels of `path` (a session without them gives no truth).
    pub fn open(path: &Path) -> Result<RecordedTruth, VisionError> {
        let reader =
            MessageReader::open(path, &[RgbdMask::TOPIC, ObjectTruth::TOPIC], ReadOptions::default())?;
        Ok(RecordedTruth { path: path.to_path_buf(), reader: reader.peekable() })
    }

    /// The true pose and mask recorded at exactly `t` (recording time), if
    /// any. Calls must come with increasing `t`: earlier messages are passed.
    pub fn at(&mut self, t: TimeNs) -> Result<(Option<SimObjectTruth>, Option<Mask>), VisionError> {
        let (mut truth, mut mask) = (None, None);
        while let Some(m) = self.reader.peek() {
            let log_time = match m {
                Ok(m) => m.log_time,
                Err(_) => TimeNs::ZERO,
            };
            if log_time > t {
                break;
            }
            let Some(m) = self.reader.next() else { break };
            let m = m?;
            if m.log_time < t {
                continue;
            }
            let bad = |e: serde_json::Error| VisionError::BadSession {
                path: self.path.clone(),
                detail: format!("{}: {e}", m.topic()),
            };
            if m.topic() == RgbdMask::TOPIC {
                let raw = serde_json::from_slice::<RgbdMask>(&m.data).map_err(bad)?.0;
                if let Some(bytes) = raw.to_mask() {
                    mask = Some(crate::cloud::mask(raw.width, raw.height, &bytes)?);
                }
            } else {
                truth = serde_json::from_slice::<ObjectTruth>(&m.data).map_err(bad)?.to_sim(t);
            }
        }
        Ok((truth, mask))
    }
}
