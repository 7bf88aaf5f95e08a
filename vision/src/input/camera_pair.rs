//! [`CameraPair`]: a live RGB-D camera as two [`Camera`]s, colour (MJPG,
//! YUYV or GREY, delivered as JPEG) and depth (`Z16`, delivered as a 16-bit
//! PNG), as the V4L2 backend of `slidetrack-drivers` exposes a RealSense-like
//! device, or as [`super::RecordedRgbd`] replays a recording. The two
//! streams are not synchronised: each depth frame is paired with the colour
//! frame closest to it in time, within a tolerance, and depth is registered
//! to the colour camera ([`register_depth_to_color`]) unless the streams
//! are registered already. A live tracker wants the newest frame: when
//! several pairs are ready, the older ones are skipped (and counted).

use std::collections::VecDeque;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use nalgebra::Isometry3;
use slidetrack_core::{Camera, CameraIntrinsics, DeviceError, ErrorKind, Frame, RgbdFrame, TimeNs};

use super::codec::{decode_color, decode_depth};
use super::registration::register_depth_to_color;
use super::source::{RgbdSample, RgbdSource};
use crate::VisionError;

/// Depth not registered to the colour camera: what moves it there.
#[derive(Clone, Debug, PartialEq)]
pub struct DepthRegistration {
    /// The depth stream's intrinsics.
    pub depth_intrinsics: CameraIntrinsics,
    /// Points in the depth camera's optical frame to the colour camera's (m).
    pub color_from_depth: Isometry3<f64>,
}

/// How a [`CameraPair`] pairs and registers.
#[derive(Clone, Debug)]
pub struct PairSettings {
    /// The colour camera's intrinsics: those of every paired frame.
    pub color_intrinsics: CameraIntrinsics,
    /// Metres per depth unit (0.001 for RealSense `Z16`).
    pub depth_scale_m: f64,
    /// Largest time between paired frames.
    pub tolerance: Duration,
    /// Longest wait for a pair before [`RgbdSource::next_frame`] fails.
    pub timeout: Duration,
    /// `None` when depth is registered to the colour camera already (its
    /// frames then have the colour frames' size).
    pub registration: Option<DepthRegistration>,
}

/// Counts of a pairing.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct PairCounts {
    /// Pairs delivered.
    pub pairs: u64,
    /// Colour frames that no depth frame came close enough to.
    pub unpaired_color: u64,
    /// Depth frames that no colour frame came close enough to.
    pub unpaired_depth: u64,
    /// Complete pairs skipped for a newer one (the reader was behind).
    pub skipped_pairs: u64,
}

/// Colour and depth cameras of one RGB-D device.
pub struct CameraPair {
    color: Box<dyn Camera>,
    depth: Box<dyn Camera>,
    settings: PairSettings,
    tolerance_ns: u64,
    colors: VecDeque<Frame>,
    depths: VecDeque<Frame>,
    sequence: u64,
    counts: PairCounts,
    ended: Option<Arc<AtomicBool>>,
    pacer: Option<Pacer>,
}

/// What moves a replay's own clock on while the reader waits; false when
/// there is nothing left to move to.
pub type Pacer = Box<dyn FnMut() -> bool + Send>;

impl CameraPair {
    /// Pairs `color` and `depth` frames as `settings` say.
    pub fn new(color: Box<dyn Camera>, depth: Box<dyn Camera>, settings: PairSettings) -> CameraPair {
        CameraPair {
            color,
            depth,
            tolerance_ns: u64::try_from(settings.tolerance.as_nanos()).unwrap_or(u64::MAX),
            settings,
            colors: VecDeque::new(),
            depths: VecDeque::new(),
            sequence: 0,
            counts: PairCounts::default(),
            ended: None,
            pacer: None,
        }
    }

    /// Ends the stream (`next_frame` gives `Ok(None)`) once `ended` is set
    /// and no pair is left: the end of a replayed recording.
    pub fn with_end(mut self, ended: Arc<AtomicBool>) -> CameraPair {
        self.ended = Some(ended);
        self
    }

    /// Waits for frames by calling `pacer` instead of sleeping: a replay on
    /// its own clock ([`super::RecordedRgbd::pacer`]).
    pub fn with_pacer(mut self, pacer: Pacer) -> CameraPair {
        self.pacer = Some(pacer);
        self
    }

    /// Pairs delivered, frames left unpaired, pairs skipped.
    pub fn counts(&self) -> PairCounts {
        self.counts
    }

    /// Pulls what the cameras have and returns the next pair, if complete:
    /// the oldest depth frame with the colour frame closest to it, once a
    /// colour frame at or after it shows that no closer one can come.
    fn try_pair(&mut self) -> Result<Option<(Frame, Frame)>, VisionError> {
        while let Some(f) = self.color.poll()? {
            self.colors.push_back(f);
        }
        while let Some(f) = self.depth.poll()? {
            self.depths.push_back(f);
        }
        let tolerance = self.tolerance_ns;
        while let Some(t) = self.depths.front().map(|d| d.t.0) {
            // Colour frames too old for this depth frame can never pair.
            while self.colors.front().is_some_and(|c| c.t.0.saturating_add(tolerance) < t) {
                self.colors.pop_front();
                self.counts.unpaired_color += 1;
            }
            if !self.colors.iter().any(|c| c.t.0 >= t) {
                // A closer colour frame may still come.
                return Ok(None);
            }
            let closest = self
                .colors
                .iter()
                .enumerate()
                .filter(|(_, c)| c.t.0.abs_diff(t) <= tolerance)
                .min_by_key(|(_, c)| c.t.0.abs_diff(t))
                .map(|(i, _)| i);
            let Some(i) = closest else {
                // Every colour frame is too new for this depth frame.
                self.depths.pop_front();
                self.counts.unpaired_depth += 1;
                continue;
            };
            self.counts.unpaired_color += i as u64;
            self.colors.drain(..i);
            let (Some(c), Some(d)) = (self.colors.pop_front(), self.depths.pop_front()) else {
                return Ok(None);
            };
            return Ok(Some((c, d)));
        }
        Ok(None)
    }

    /// The newest complete pair, skipping older complete ones.
    fn newest_pair(&mut self) -> Result<Option<(Frame, Frame)>, VisionError> {
        let mut newest = None;
        while let Some(pair) = self.try_pair()? {
            if newest.replace(pair).is_some() {
                self.counts.skipped_pairs += 1;
            }
        }
        Ok(newest)
    }

    /// An RGB-D frame of a colour and a depth frame.
    fn rgbd(&mut self, c: Frame, d: Frame) -> Result<RgbdFrame, VisionError> {
        let bad = |what: &'static str| VisionError::BadImage {
            what,
            detail: "the camera delivered no encoded image".into(),
        };
        let color = decode_color(&c.encoded.ok_or(bad("colour frame"))?.bytes)?;
        let mut depth =
            decode_depth(&d.encoded.ok_or(bad("depth frame"))?.bytes, self.settings.depth_scale_m)?;
        let k = &self.settings.color_intrinsics;
        VisionError::check_size("colour frame", (color.width, color.height), (k.width, k.height))?;
        if let Some(r) = &self.settings.registration {
            depth = register_depth_to_color(&depth, &r.depth_intrinsics, k, &r.color_from_depth)?;
        }
        VisionError::check_size(
            "depth frame (registered depth has the colour frames' size)",
            (depth.width, depth.height),
            (color.width, color.height),
        )?;
        let frame =
            RgbdFrame { t: TimeNs(d.t.0), sequence: self.sequence, color, depth, intrinsics: k.clone() };
        self.sequence += 1;
        self.counts.pairs += 1;
        Ok(frame)
    }
}

impl RgbdSource for CameraPair {
    fn intrinsics(&self) -> &CameraIntrinsics {
        &self.settings.color_intrinsics
    }

    /// Blocks (polling every millisecond) until a pair is complete, and
    /// returns the newest; the frame's time is the depth frame's. Ends with
    /// the cameras' error when one fails, a timeout error when no pair
    /// completes within the settings' timeout, and `Ok(None)` at the end of
    /// a replay (see [`CameraPair::with_end`]).
    fn next_frame(&mut self) -> Result<Option<RgbdSample>, VisionError> {
        let started = Instant::now();
        loop {
            let ended = self.ended.as_ref().is_some_and(|e| e.load(Ordering::SeqCst));
            if let Some((c, d)) = self.newest_pair()? {
                let frame = self.rgbd(c, d)?;
                return Ok(Some(RgbdSample { frame, truth: None, truth_mask: None }));
            }
            if ended {
                return Ok(None);
            }
            if self.pacer.as_mut().is_some_and(|pace| pace()) {
                continue;
            }
            if started.elapsed() > self.settings.timeout {
                let detail = format!(
                    "no colour and depth frames within {:.1} ms of each other for {:.1} s (colour from {}; {:?})",
                    self.settings.tolerance.as_secs_f64() * 1e3,
                    self.settings.timeout.as_secs_f64(),
                    self.color.device(),
                    self.counts
                );
                return Err(DeviceError::new(ErrorKind::Timeout, self.depth.device(), detail).into());
            }
            std::thread::sleep(Duration::from_millis(1));
        }
    }
}

#[cfg(test)]
mod tests;
