//! A collected trial with a vision tracker beside it (`collect --vision`):
//! on a hardware rig whose RGB-D camera is also the marker camera
//! (`[hw.camera] kind = "rgbd"`), one opening of the camera feeds the
//! marker's ground truth, the tracker (on its own thread, recording its
//! measurements and estimates) and the recording of colour, depth and
//! calibration.

use std::path::Path;
use std::sync::atomic::AtomicBool;
use std::sync::{Arc, Mutex};

use anyhow::{Context, Result, bail};
use slidetrack_control::{Baseline, ObserverError};
use slidetrack_core::{Frame, TimeNs};
use slidetrack_drivers::config::CameraDevice;
use slidetrack_vision::live::LiveThread;

use crate::observer::TrialExtension;
use crate::rig::{RigKind, TrialSpec, build_rig};
use crate::tracking::{CameraVisionSummary, VisionEnd};
use crate::trial::{ExtensionFactory, TrialReport, record_trial, record_trial_with};
use crate::vision::camera_vision::{self, CameraVision, CameraVisionOptions};

/// A collected trial and, with a vision tracker, what it did.
pub struct CollectedTrial {
    /// The trial's report.
    pub report: TrialReport,
    /// The vision tracker's summary, with `--vision`.
    pub vision: Option<CameraVisionSummary>,
}

/// Runs the trial of `spec` on a `kind` rig and records it; with `vision`
/// (its options and the rig TOML's path), a vision tracker on the rig's
/// shared RGB-D camera beside it. The options are checked before any
/// device opens.
pub fn collect_trial(
    kind: RigKind,
    spec: &TrialSpec<'_>,
    vision: Option<(&CameraVisionOptions<'_>, &Path)>,
    stop: &AtomicBool,
    progress: &mut dyn FnMut(TimeNs),
) -> Result<CollectedTrial> {
    let Some((options, rig_path)) = vision else {
        let report = record_trial(build_rig(kind, spec)?, spec, stop, progress)?;
        return Ok(CollectedTrial { report, vision: None });
    };
    camera_vision::requirements(options, spec.rig, rig_path)?;
    let shared = spec.rig.hw.as_ref().is_some_and(|hw| matches!(hw.camera, CameraDevice::Rgbd(_)));
    if kind != RigKind::Hw || !shared || !spec.camera {
        bail!(
            "collect --vision tracks the RGB-D camera that is also the marker camera: --rig hw with \
             [hw.camera] kind = \"rgbd\" in {}, and the camera on (no --no-camera)",
            rig_path.display()
        );
    }
    let mut setup = build_rig(kind, spec)?;
    let frames = setup.rgbd_frames.take().context("internal: the shared RGB-D camera has no frames")?;
    let replayed = setup.rgbd.as_ref().and_then(|r| r.replay.clone());
    let CameraVision { tracking, camera, metadata, end, .. } =
        camera_vision::open_shared(options, spec.rig, rig_path, frames, replayed)?;
    setup.extra_metadata.extend(metadata);
    let summary = Arc::new(Mutex::new(None));
    let out = Arc::clone(&summary);
    let extension: ExtensionFactory = Box::new(move |logger, _| {
        let thread = tracking.recording_estimates_to(logger)?.spawn(camera);
        Ok(Box::new(VisionBeside { thread: Some((thread, end)), summary: out }) as Box<_>)
    });
    let report = record_trial_with(setup, spec, stop, progress, Some(extension))?;
    let vision = summary.lock().ok().and_then(|mut s| s.take());
    Ok(CollectedTrial { report, vision })
}

/// The vision tracker's thread as a trial extension: stopped with the
/// trial (before the session is finished), its summary kept.
struct VisionBeside {
    thread: Option<(LiveThread, VisionEnd)>,
    summary: Arc<Mutex<Option<CameraVisionSummary>>>,
}

impl TrialExtension for VisionBeside {
    fn on_zeroed(&mut self, _t: TimeNs, _zeroed: &Baseline) -> Result<(), ObserverError> {
        Ok(())
    }

    fn on_frame(&mut self, _frame: &Frame, _position_on_axis_m: Option<f64>) -> Result<(), ObserverError> {
        Ok(())
    }
}

impl Drop for VisionBeside {
    fn drop(&mut self) {
        let Some((thread, end)) = self.thread.take() else { return };
        let summary = CameraVisionSummary::of(thread, end);
        if let Ok(mut s) = self.summary.lock() {
            *s = Some(summary);
        }
    }
}
