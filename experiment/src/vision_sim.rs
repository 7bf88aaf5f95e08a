//! The vision trackers on the simulator's RGB-D sequences: the simulated
//! camera as an [`RgbdSource`], the ROFT variants of Table 5.6 and MaskUKF
//! on simulated fast sequences.

use nalgebra::Isometry3;
use slidetrack_core::CameraIntrinsics;
use slidetrack_estimators::metrics::summarize;
use slidetrack_sim::rgbd::{FastSequence, FastSequenceConfig, RgbdSimError};
use slidetrack_vision::eval::{TrackedFrame, Variant, VariantResult, track, variant_errors};
use slidetrack_vision::input::{RgbdSample, RgbdSource};
use slidetrack_vision::sources::{SlowNetworkConfig, TruthSource};
use slidetrack_vision::{ObjectModel, TrackerKind, TrackerSettings, VisionError, build_tracker};
use thiserror::Error;

/// Why a tracker could not run on a simulated scene.
#[derive(Debug, Error)]
pub enum VisionSimError {
    /// The simulated scene could not be built.
    #[error("simulated RGB-D camera")]
    Scene(#[from] RgbdSimError),
    /// The tracker or its inputs failed.
    #[error(transparent)]
    Vision(#[from] VisionError),
}

/// The simulated RGB-D camera looking at a fast object.
pub struct SimRgbd {
    sequence: FastSequence,
    next: usize,
}

impl SimRgbd {
    /// Frames of `sequence`, from the first.
    pub fn new(sequence: FastSequence) -> SimRgbd {
        SimRgbd { sequence, next: 0 }
    }

    /// The sequence.
    pub fn sequence(&self) -> &FastSequence {
        &self.sequence
    }
}

impl RgbdSource for SimRgbd {
    fn intrinsics(&self) -> &CameraIntrinsics {
        self.sequence.intrinsics()
    }

    fn next_frame(&mut self) -> Result<Option<RgbdSample>, VisionError> {
        if self.next >= self.sequence.len() {
            return Ok(None);
        }
        let (frame, mask, truth) = self.sequence.frame(self.next);
        self.next += 1;
        let truth_mask = slidetrack_vision::cloud::mask(frame.depth.width, frame.depth.height, &mask)?;
        Ok(Some(RgbdSample { frame, truth: Some(truth), truth_mask: Some(truth_mask) }))
    }

    fn len_hint(&self) -> Option<usize> {
        Some(self.sequence.len())
    }
}

/// Runs `variant` on simulated fast sequences and scores all their frames
/// together (as the "ALL" rows of the thesis tables). Each sequence's first
/// `network.latency_s` of frames is left out: no variant has an estimate
/// before the network's first result.
pub fn evaluate_variant(
    variant: Variant,
    sequences: &[FastSequenceConfig],
    network: &SlowNetworkConfig,
    settings: &TrackerSettings,
) -> Result<VariantResult, VisionSimError> {
    let mut all_errors = Vec::new();
    for config in sequences {
        let sequence = FastSequence::new(config.clone())?;
        let model = ObjectModel::from_mesh(config.object.name(), sequence.mesh().clone());
        let skip = (network.latency_s * config.fps).ceil() as usize;
        let mut source = SimRgbd::new(sequence);
        let network_config = SlowNetworkConfig { seed: network.seed ^ config.motion.seed, ..network.clone() };
        // Errors of each sequence against its own model, then pooled.
        all_errors.extend(variant_errors(variant, &mut source, &model, skip, &network_config, settings)?);
    }
    Ok(VariantResult { variant, label: variant.label(), metrics: summarize(&all_errors) })
}

/// MaskUKF on a simulated sequence with the true masks of every frame,
/// started at `start` (for example 5 cm and 10 degrees off the truth).
pub fn maskukf_on_sequence(
    config: &FastSequenceConfig,
    start: Isometry3<f64>,
    settings: &TrackerSettings,
) -> Result<(Vec<TrackedFrame>, ObjectModel), VisionSimError> {
    let sequence = FastSequence::new(config.clone())?;
    let model = ObjectModel::from_mesh(config.object.name(), sequence.mesh().clone());
    let intrinsics = sequence.intrinsics().clone();
    let s = TrackerSettings { initial_pose: Some(start), ..settings.clone() };
    let mut tracker = build_tracker(TrackerKind::MaskUkf, &model, &intrinsics, &s)?;
    let mut source = SimRgbd::new(sequence);
    let mut truth = TruthSource { masks: true, poses: false };
    let frames = track(&mut source, &mut truth, Some(tracker.as_mut()), |_, _| {})?;
    Ok((frames, model))
}
