//! [`SessionRgbd`]: the RGB-D frames of a recorded session (`/rgbd/color`,
//! `/rgbd/depth`, `/rgbd/calibration`, and on simulated sessions
//! `/rgbd/mask` and `/sim/object`), read in order with bounded memory.

use std::iter::Peekable;
use std::path::{Path, PathBuf};

use slidetrack_core::{CameraIntrinsics, RgbdFrame, TimeNs};
use slidetrack_session::{
    ChannelMessage, MessageReader, ObjectTruth, RawMessage, ReadOptions, RgbdCalibration, RgbdColor,
    RgbdDepth, RgbdMask, read_channel,
};

use super::codec::decode_color;
use super::source::{RgbdSample, RgbdSource};
use crate::VisionError;

/// The RGB-D frames of a session.
pub struct SessionRgbd {
    path: PathBuf,
    intrinsics: CameraIntrinsics,
    reader: Peekable<MessageReader>,
    frames: usize,
    sequence: u64,
}

impl SessionRgbd {
    /// Opens `path`; fails when it has no `/rgbd/calibration` or no depth.
    pub fn open(path: &Path, options: ReadOptions) -> Result<SessionRgbd, VisionError> {
        let bad = |detail: &str| VisionError::BadSession { path: path.to_path_buf(), detail: detail.into() };
        let calibration = read_channel::<RgbdCalibration>(path, options)
            .map_err(|_| bad("no /rgbd/calibration channel: not an RGB-D session (record one with `slidetrack vision simulate`)"))?;
        let intrinsics = calibration
            .first()
            .and_then(|(_, c)| c.0.intrinsics())
            .ok_or_else(|| bad("/rgbd/calibration holds no usable plumb_bob calibration"))?;
        let info = slidetrack_session::SessionInfo::read(path, options)?;
        let frames = info.channel(RgbdDepth::TOPIC).map_or(0, |c| c.message_count as usize);
        if frames == 0 {
            return Err(bad("no /rgbd/depth frames"));
        }
        let topics = [RgbdColor::TOPIC, RgbdDepth::TOPIC, RgbdMask::TOPIC, ObjectTruth::TOPIC];
        let reader = MessageReader::open(path, &topics, options)?.peekable();
        Ok(SessionRgbd { path: path.to_path_buf(), intrinsics, reader, frames, sequence: 0 })
    }

    fn bad(&self, detail: String) -> VisionError {
        VisionError::BadSession { path: self.path.clone(), detail }
    }

    /// The messages logged at the next log time.
    fn next_group(&mut self) -> Result<Option<(TimeNs, Vec<RawMessage>)>, VisionError> {
        let Some(first) = self.reader.next() else {
            return Ok(None);
        };
        let first = first?;
        let t = first.log_time;
        let mut group = vec![first];
        while let Some(Ok(m)) = self.reader.peek() {
            if m.log_time != t {
                break;
            }
            if let Some(Ok(m)) = self.reader.next() {
                group.push(m);
            }
        }
        Ok(Some((t, group)))
    }
}

impl RgbdSource for SessionRgbd {
    fn intrinsics(&self) -> &CameraIntrinsics {
        &self.intrinsics
    }

    fn next_frame(&mut self) -> Result<Option<RgbdSample>, VisionError> {
        loop {
            let Some((t, group)) = self.next_group()? else {
                return Ok(None);
            };
            let (mut color, mut depth, mut mask, mut truth) = (None, None, None, None);
            for m in &group {
                let decode = |e: serde_json::Error| VisionError::BadSession {
                    path: self.path.clone(),
                    detail: format!("{}: {e}", m.topic()),
                };
                match m.topic() {
                    t if t == RgbdColor::TOPIC => {
                        color = Some(serde_json::from_slice::<RgbdColor>(&m.data).map_err(decode)?)
                    }
                    t if t == RgbdDepth::TOPIC => {
                        depth = Some(serde_json::from_slice::<RgbdDepth>(&m.data).map_err(decode)?)
                    }
                    t if t == RgbdMask::TOPIC => {
                        mask = Some(serde_json::from_slice::<RgbdMask>(&m.data).map_err(decode)?)
                    }
                    _ => truth = Some(serde_json::from_slice::<ObjectTruth>(&m.data).map_err(decode)?),
                }
            }
            // A frame needs colour and depth; lone messages are skipped.
            let (Some(color), Some(depth)) = (color, depth) else {
                continue;
            };
            let color = decode_color(&color.0.data)?;
            let depth = depth.to_depth().map_err(|e| self.bad(e.to_string()))?;
            if (color.width, color.height) != (depth.width, depth.height)
                || (depth.width, depth.height) != (self.intrinsics.width, self.intrinsics.height)
            {
                return Err(VisionError::SizeMismatch {
                    what: "RGB-D frame",
                    width: depth.width,
                    height: depth.height,
                    expected_width: self.intrinsics.width,
                    expected_height: self.intrinsics.height,
                });
            }
            let truth_mask = match mask.and_then(|m| m.0.to_mask().map(|b| (m.0.width, m.0.height, b))) {
                Some((w, h, bytes)) => Some(crate::cloud::mask(w, h, &bytes)?),
                None => None,
            };
            let frame =
                RgbdFrame { t, sequence: self.sequence, color, depth, intrinsics: self.intrinsics.clone() };
            self.sequence += 1;
            let truth = truth.and_then(|o| o.to_sim(t));
            return Ok(Some(RgbdSample { frame, truth, truth_mask }));
        }
    }

    fn len_hint(&self) -> Option<usize> {
        Some(self.frames)
    }
}
