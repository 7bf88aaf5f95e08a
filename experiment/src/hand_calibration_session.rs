//! `calibrate hand --session`: the camera's pose in the hand frame from the
//! colour frames of a recorded session that show the hand's target
//! (`[hand_target]` of the rig TOML), with the session's camera calibration.
//!
//! Also writes such a session from the simulated camera
//! ([`record_hand_target_session`]), for tests and demonstrations.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use nalgebra::Isometry3;
use slidetrack_calibration::encode_jpeg;
use slidetrack_core::{CameraIntrinsics, TimeNs};
use slidetrack_session::{
    CameraCalibration, CompressedImage, MessageReader, ReadOptions, Recorder, RgbdCalibration, RgbdColor,
    SessionInfo, read_json,
};
use slidetrack_vision::input::decode_color;

use crate::hand_calibration::{HandCalibrationRun, Sources, finish, hand_target, target_renderer};
use crate::hand_target::TargetFinder;
use crate::rig_config::RigConfig;

/// The colour channels a session may hold, each with its calibration
/// channel, in the order they are looked for.
const IMAGE_CHANNELS: [(&str, &str); 2] =
    [("/camera/image", "/camera/calibration"), ("/rgbd/color", "/rgbd/calibration")];

/// Estimates the camera's placement in the hand frame from the frames of
/// `session` in which `[hand_target]` of `config` is seen. `frames` limits
/// the frames looked at, evenly spread over the session (all by default).
pub fn calibrate_hand_session(
    session: &Path,
    config: Option<&Path>,
    frames: Option<usize>,
    out: Option<&Path>,
) -> Result<HandCalibrationRun> {
    if frames == Some(0) {
        bail!("--frames must be at least 1");
    }
    let rig = RigConfig::load(config)?;
    let target = hand_target(&rig)?;
    let hand_from_target = target.hand_from_target.isometry()?;
    let info = SessionInfo::read(session, ReadOptions::default())?;
    let Some((topic, calibration_topic, count)) = IMAGE_CHANNELS.iter().find_map(|(image, cal)| {
        info.channel(image).filter(|c| c.message_count > 0).map(|c| (*image, *cal, c.message_count as usize))
    }) else {
        bail!(
            "{}: no colour frames (no messages on /camera/image or /rgbd/color): record the session with a camera in view of the hand's target",
            session.display()
        );
    };
    let (intrinsics, intrinsics_from) = session_intrinsics(session, calibration_topic, &rig)?;
    let selected = spread(count, frames.unwrap_or(count));
    let mut finder = TargetFinder::new(&target)?;
    let mut views = Vec::with_capacity(selected.len());
    let reader = MessageReader::open(session, &[topic], ReadOptions::default())?;
    let mut wanted = selected.iter().copied().peekable();
    for (index, message) in reader.enumerate() {
        let message = message?;
        if wanted.peek() != Some(&index) {
            continue;
        }
        wanted.next();
        let at =
            || format!("{}: {topic} frame {index} (log time {} ns)", session.display(), message.log_time.0);
        let frame: CompressedImage = serde_json::from_slice(&message.data).with_context(at)?;
        let image = decode_color(&frame.data).with_context(at)?;
        if (image.width, image.height) != (intrinsics.width, intrinsics.height) {
            bail!(
                "{}: the frame is {}x{} px but the intrinsics ({intrinsics_from}) are for {}x{} px",
                at(),
                image.width,
                image.height,
                intrinsics.width,
                intrinsics.height
            );
        }
        views.extend(finder.view(&image, &intrinsics)?);
    }
    if views.is_empty() {
        bail!(
            "{}: the hand's target ({}, [hand_target]) is seen in none of the {} frames of {topic} looked at",
            session.display(),
            target.describe(),
            selected.len()
        );
    }
    let sources = Sources {
        frames_from: format!("{} {topic}", session.display()),
        intrinsics_from,
        frames_read: selected.len(),
    };
    finish(&hand_from_target, &views, sources, None, out)
}

/// The intrinsics of the session's `topic` (its first message), else the rig
/// config's camera, with where they came from.
fn session_intrinsics(session: &Path, topic: &str, rig: &RigConfig) -> Result<(CameraIntrinsics, String)> {
    let recorded = match read_json::<CameraCalibration>(session, topic, ReadOptions::default()) {
        Ok(messages) => messages.into_iter().next(),
        Err(slidetrack_session::SessionError::NoSuchTopic { .. }) => None,
        Err(e) => return Err(e.into()),
    };
    if let Some((_, message)) = recorded {
        let Some(intrinsics) = message.intrinsics() else {
            bail!(
                "{}: {topic} has distortion model {:?} with {} coefficients; only plumb_bob with 5 is read",
                session.display(),
                message.distortion_model,
                message.d.len()
            );
        };
        return Ok((intrinsics, format!("the session's {topic}")));
    }
    rig_intrinsics(rig)
}

/// The rig config's camera: `[hw.camera]`'s calibration for a V4L2 camera,
/// else `[camera]` (the simulated camera's intrinsics).
fn rig_intrinsics(rig: &RigConfig) -> Result<(CameraIntrinsics, String)> {
    #[cfg(all(feature = "devices", target_os = "linux"))]
    if let Some(slidetrack_drivers::config::CameraDevice::V4l2(v)) = rig.hw.as_ref().map(|hw| &hw.camera) {
        let intrinsics = crate::v4l2_intrinsics::v4l2_intrinsics(v)?;
        return Ok((intrinsics, "the rig config's [hw.camera] calibration (the session has none)".into()));
    }
    Ok((rig.camera.intrinsics.clone(), "the rig config's [camera] intrinsics (the session has none)".into()))
}

/// `wanted` indices of `0..count`, evenly spread (the first, then every
/// `count / wanted`-th); all of them when `wanted >= count`.
pub fn spread(count: usize, wanted: usize) -> Vec<usize> {
    if wanted >= count {
        return (0..count).collect();
    }
    (0..wanted).map(|k| k * count / wanted).collect()
}

/// What [`record_hand_target_session`] writes.
#[derive(Clone, Debug)]
pub struct HandTargetRecording {
    /// The rig configuration (TOML) with `[camera]` and `[hand_target]`.
    pub config: Option<PathBuf>,
    /// Frames to render.
    pub frames: usize,
    /// Seed of the simulated camera's noise.
    pub seed: u64,
    /// Write `/camera/calibration` (the simulated camera's intrinsics).
    pub with_calibration: bool,
    /// Write the frames and the calibration as an RGB-D camera's colour
    /// stream does, on `/rgbd/color` and `/rgbd/calibration`.
    pub rgbd: bool,
    /// The session file to create.
    pub out: PathBuf,
}

/// Writes a session whose `/camera/image` (or, with `rgbd`, `/rgbd/color`)
/// holds the simulated camera's frames (JPEG, 30 Hz) of the hand's target,
/// and `/camera/calibration` (`/rgbd/calibration`) when asked; returns the
/// camera's true placement in the hand frame.
pub fn record_hand_target_session(options: &HandTargetRecording) -> Result<Isometry3<f64>> {
    let rig = RigConfig::load(options.config.as_deref())?;
    let target = hand_target(&rig)?;
    let hand_from_target = target.hand_from_target.isometry()?;
    let (mut renderer, hand_from_plate) = target_renderer(&rig, &target, &hand_from_target, options.seed)?;
    let recorder = Recorder::create(&options.out, BTreeMap::new())?;
    let (images, rgbd_images) = if options.rgbd {
        (None, Some(recorder.register::<RgbdColor>(BTreeMap::new())?))
    } else {
        (Some(recorder.register::<CompressedImage>(BTreeMap::new())?), None)
    };
    if options.with_calibration {
        let message = CameraCalibration::new(TimeNs::ZERO, "camera", renderer.intrinsics());
        if options.rgbd {
            let ch = recorder.register::<RgbdCalibration>(BTreeMap::new())?;
            recorder.log_json(&ch, TimeNs::ZERO, TimeNs::ZERO, 0, &RgbdCalibration(message))?;
        } else {
            let ch = recorder.register::<CameraCalibration>(BTreeMap::new())?;
            recorder.log_json(&ch, TimeNs::ZERO, TimeNs::ZERO, 0, &message)?;
        }
    }
    for k in 0..options.frames {
        let t = TimeNs(k as u64 * 1_000_000_000 / 30);
        let jpeg = encode_jpeg(&renderer.render_image(&hand_from_plate, k as u64), rig.camera.jpeg_quality)?;
        let message = CompressedImage::new(t, "camera", &jpeg);
        if let Some(ch) = &images {
            recorder.log_json(ch, t, t, k as u32, &message)?;
        }
        if let Some(ch) = &rgbd_images {
            recorder.log_json(ch, t, t, k as u32, &RgbdColor(message))?;
        }
    }
    recorder.finish().with_context(|| format!("cannot write {}", options.out.display()))?;
    Ok(*renderer.hand_from_camera())
}

#[cfg(test)]
mod tests {
    use super::spread;

    #[test]
    fn hand_frames_are_spread_evenly_over_the_session() {
        assert_eq!(spread(10, 5), vec![0, 2, 4, 6, 8]);
        assert_eq!(spread(10, 3), vec![0, 3, 6]);
        assert_eq!(spread(4, 10), vec![0, 1, 2, 3]);
        assert_eq!(spread(7, 7), (0..7).collect::<Vec<_>>());
        assert!(spread(5, 0).is_empty());
    }
}
