//! `calibrate hand`: the camera's pose in the hand frame from a marker fixed
//! to the hand at a known mount pose (`[hand_target]` in the rig TOML).
//!
//! With `--rig sim` the simulated camera renders the hand's target (the
//! object is not in the scene) for a number of frames; the result is compared
//! with the simulated camera's configured placement. With `--session` the
//! frames are a recorded session's colour images (`hand_calibration_session`).

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use nalgebra::Isometry3;
use serde::Serialize;
use slidetrack_calibration::hand_eye::{
    HandCalibration, HandEyeOptions, TargetView, estimate_hand_from_camera, pose_difference,
};
use slidetrack_calibration::{Dictionary, board_patterns, marker_pattern};
use slidetrack_sim::camera::{BoardPrint, ObjectAppearance, SimCameraRenderer};

use crate::hand_target::{HandTargetConfig, TargetFinder};
use crate::rig_config::RigConfig;

/// What `calibrate hand` reads.
#[derive(Clone, Debug)]
pub struct HandCalibrationOptions {
    /// The rig configuration (TOML) with `[hand_target]`.
    pub config: Option<PathBuf>,
    /// Frames to render from the simulated camera (default 30), or the most
    /// frames to take from a session, evenly spread over it (default all).
    pub frames: Option<usize>,
    /// Seed of the simulated camera's noise.
    pub seed: u64,
    /// Where to write the `[camera] placement` (TOML), if anywhere.
    pub out: Option<PathBuf>,
}

/// The result, and the simulator's truth to compare it with.
#[derive(Clone, Debug, Serialize)]
pub struct HandCalibrationRun {
    /// The estimate and its uncertainty.
    pub calibration: HandCalibration,
    /// The ready-to-paste `placement = ...` line.
    pub placement_toml: String,
    /// Error against the simulated camera's true placement (mm, degrees).
    pub sim_error_mm_deg: Option<(f64, f64)>,
    /// Where the frames came from: `simulated camera`, or the session file
    /// and its image channel.
    pub frames_from: String,
    /// Where the intrinsics came from.
    pub intrinsics_from: String,
    /// Frames looked at.
    pub frames_read: usize,
    /// Frames in which the target (its marker, or a board's pose) was found.
    pub frames_with_target: usize,
}

/// Frames the simulated camera renders unless `--frames` says otherwise.
pub const DEFAULT_SIM_FRAMES: usize = 30;

/// Renders the hand's target with the simulated camera and estimates the
/// camera's placement in the hand frame.
pub fn calibrate_hand_sim(options: &HandCalibrationOptions) -> Result<HandCalibrationRun> {
    let rig = RigConfig::load(options.config.as_deref())?;
    let target = hand_target(&rig)?;
    let hand_from_target = target.hand_from_target.isometry()?;
    let (mut renderer, hand_from_plate) = target_renderer(&rig, &target, &hand_from_target, options.seed)?;
    let mut finder = TargetFinder::new(&target)?;
    let frames = options.frames.unwrap_or(DEFAULT_SIM_FRAMES);
    let mut views = Vec::with_capacity(frames);
    for k in 0..frames as u64 {
        let image = renderer.render_image(&hand_from_plate, k);
        views.extend(finder.view(&image, renderer.intrinsics())?);
    }
    let truth = *renderer.hand_from_camera();
    let sources = Sources {
        frames_from: "simulated camera".into(),
        intrinsics_from: "the rig config's [camera] (simulated camera)".into(),
        frames_read: frames,
    };
    finish(&hand_from_target, &views, sources, Some(&truth), options.out.as_deref())
}

/// Where a run's frames and intrinsics came from.
pub(crate) struct Sources {
    pub frames_from: String,
    pub intrinsics_from: String,
    pub frames_read: usize,
}

/// Estimates from `views` (with the usual outlier rules), compares with
/// `truth` when known, and writes `out` when given.
pub(crate) fn finish(
    hand_from_target: &Isometry3<f64>,
    views: &[TargetView],
    sources: Sources,
    truth: Option<&Isometry3<f64>>,
    out: Option<&Path>,
) -> Result<HandCalibrationRun> {
    let calibration = estimate_hand_from_camera(hand_from_target, views, &HandEyeOptions::default())
        .context("calibrate hand")?;
    let run = HandCalibrationRun {
        placement_toml: calibration.placement_toml(),
        sim_error_mm_deg: truth.map(|t| pose_difference(&calibration.hand_from_camera(), t)),
        calibration,
        frames_from: sources.frames_from,
        intrinsics_from: sources.intrinsics_from,
        frames_read: sources.frames_read,
        frames_with_target: views.len(),
    };
    if let Some(out) = out {
        write_placement(out, &run)?;
    }
    Ok(run)
}

/// The rig's `[hand_target]`, or the error saying it has none.
pub(crate) fn hand_target(rig: &RigConfig) -> Result<HandTargetConfig> {
    rig.hand_target.clone().context(
        "the rig config has no [hand_target] (dictionary, id, marker_size_m or board, hand_from_target): nothing to calibrate against",
    )
}

/// The simulated camera with the hand's marker (or board) printed on a
/// plate (drawn as the "object" face), and the plate's pose in the hand frame.
pub(crate) fn target_renderer(
    rig: &RigConfig,
    target: &HandTargetConfig,
    hand_from_target: &Isometry3<f64>,
    seed: u64,
) -> Result<(SimCameraRenderer, Isometry3<f64>)> {
    let (face_size_m, marker_size_m) = match &target.board {
        None => ([target.marker_size_m * 1.6; 2], target.marker_size_m),
        Some(layout) => {
            let [w, h] = layout.size_m();
            let margin_m = 0.6 * layout.marker_length_m();
            ([w + margin_m, h + margin_m], layout.marker_length_m())
        }
    };
    let appearance = ObjectAppearance {
        face_size_m,
        marker_size_m,
        marker_centre_on_face_m: [0.0, 0.0],
        ..ObjectAppearance::default()
    };
    // A board's centre frame is the renderer's "marker" frame.
    let hand_from_plate = hand_from_target * appearance.object_from_marker().inverse();
    let (config, seed) = (rig.camera.clone(), seed);
    let renderer = match &target.board {
        None => {
            SimCameraRenderer::new(config, appearance, marker_pattern(&target.dictionary, target.id)?, seed)?
        }
        Some(layout) => {
            let markers = board_patterns(layout, &Dictionary::from_name(&target.dictionary)?)?;
            SimCameraRenderer::with_board(
                config,
                appearance,
                BoardPrint { layout: layout.clone(), markers },
                seed,
            )?
        }
    };
    Ok((renderer, hand_from_plate))
}

/// Writes `[camera]` with the placement line, the uncertainty as comments.
fn write_placement(path: &Path, run: &HandCalibrationRun) -> Result<()> {
    let c = &run.calibration;
    let text = format!(
        "# calibrate hand ({}): {} frames; standard error {:.3} mm, {:.4} deg; per-frame spread {:.3} mm, {:.4} deg\n[camera]\n{}\n",
        run.frames_from,
        c.frames_used,
        c.translation_std_error_mm,
        c.rotation_std_error_deg,
        c.translation_spread_mm,
        c.rotation_spread_deg,
        run.placement_toml
    );
    std::fs::write(path, text).with_context(|| format!("cannot write {}", path.display()))
}
