//! The trackers scored against ground truth (`vision eval`): on simulated
//! fast sequences (the variants of Table 5.6 and MaskUKF), or on inputs with
//! a true pose tracked as `vision track` would.

use std::path::PathBuf;

use anyhow::{Context, Result};
use serde::Serialize;
use slidetrack_estimators::metrics::{perturbed_start, summarize};
use slidetrack_sim::rgbd::{FastSequence, FastSequenceConfig, SimObjectKind};
use slidetrack_vision::eval::{Scored, Variant, errors, track};
use slidetrack_vision::sources::SlowNetworkConfig;
use slidetrack_vision::{TrackerKind, TrackerSettings, build_tracker};

use super::input::{InputOptions, Prepared, prepare};
use super::{Measurements, SequenceMetrics, TrackerStart};
use crate::vision_sim::{evaluate_variant, maskukf_on_sequence};

/// One row of the results: what was scored and its errors.
#[derive(Clone, Debug, Serialize)]
pub struct ScoreRow {
    /// The variant or the input.
    pub label: String,
    /// Its errors against the truth.
    #[serde(flatten)]
    pub metrics: SequenceMetrics,
}

/// The simulated fast sequences to score on.
#[derive(Clone, Debug)]
pub struct SimulatedEvalOptions {
    /// Simulated sequences per object.
    pub sequences: usize,
    /// The objects' names; all six when empty.
    pub objects: Vec<String>,
    /// Length of each sequence (s).
    pub duration_s: f64,
    /// Seed of the first sequence.
    pub seed: u64,
    /// All the ROFT variants of Table 5.6 instead of ROFT and the network.
    pub ablation: bool,
}

/// Where a simulated evaluation is.
#[derive(Clone, Copy, Debug)]
pub enum EvalStep<'a> {
    /// This many steps are coming.
    Total(u64),
    /// A step starts: its label.
    Start(&'a str),
    /// A step is done.
    Done,
}

/// The simulated fast sequences of `options`.
fn sequences(options: &SimulatedEvalOptions) -> Result<Vec<FastSequenceConfig>> {
    let kinds: Vec<SimObjectKind> = if options.objects.is_empty() {
        SimObjectKind::ALL.to_vec()
    } else {
        options
            .objects
            .iter()
            .map(|o| SimObjectKind::from_name(o).with_context(|| format!("unknown object '{o}'")))
            .collect::<Result<_>>()?
    };
    anyhow::ensure!(options.duration_s >= 1.0, "--duration must be at least 1 s");
    let mut out = Vec::new();
    for (i, kind) in kinds.iter().enumerate() {
        for s in 0..options.sequences.max(1) {
            let seed = options.seed + (i * options.sequences.max(1) + s) as u64;
            out.push(FastSequenceConfig::new(*kind, options.duration_s, seed));
        }
    }
    Ok(out)
}

/// The variants (ROFT and the network, or Table 5.6) and MaskUKF scored on
/// the simulated sequences of `options`; `on_step` hears of each variant.
pub fn simulated(
    options: &SimulatedEvalOptions,
    on_step: &mut dyn FnMut(EvalStep<'_>),
) -> Result<Vec<ScoreRow>> {
    let configs = sequences(options)?;
    let network = SlowNetworkConfig::default();
    let settings = TrackerSettings::default();
    let variants: Vec<Variant> =
        if options.ablation { Variant::TABLE_5_6.to_vec() } else { vec![Variant::Roft, Variant::Network] };
    on_step(EvalStep::Total(variants.len() as u64 + 1));
    let mut rows = Vec::new();
    for v in variants {
        on_step(EvalStep::Start(v.label()));
        let r = evaluate_variant(v, &configs, &network, &settings)?;
        rows.push(ScoreRow { label: r.label.to_string(), metrics: r.metrics });
        on_step(EvalStep::Done);
    }
    // MaskUKF with the true masks of every frame, started 5 cm and 10 degrees
    // off, on the fast sequences and on the same paths at YCB-Video-like
    // speeds (15 cm/s, 45 deg/s), for which its motion model is tuned.
    on_step(EvalStep::Start("MaskUKF"));
    for (label, slow) in
        [("MaskUKF (true masks, start 5 cm / 10 deg off)", false), ("MaskUKF (same, YCB-Video speeds)", true)]
    {
        let mut all = Vec::new();
        for c in &configs {
            let mut c = c.clone();
            if slow {
                c.motion.max_speed_mps = c.motion.max_speed_mps.min(0.15);
                c.motion.max_angular_speed_dps = c.motion.max_angular_speed_dps.min(45.0);
            }
            let first = FastSequence::new(c.clone())?.truth(0).camera_from_object;
            let (frames, model) = maskukf_on_sequence(&c, perturbed_start(&first), &settings)?;
            all.extend(errors(&frames, 0, Scored::Tracker, &*model.object_points()?));
        }
        rows.push(ScoreRow { label: label.into(), metrics: summarize(&all) });
    }
    Ok(rows)
}

/// Inputs with ground truth to score a tracker on.
#[derive(Clone, Debug)]
pub struct InputEvalOptions<'a> {
    /// Sessions with `/sim/object`, or YCB-Video-style directories.
    pub inputs: &'a [PathBuf],
    /// The tracker.
    pub kind: TrackerKind,
    /// The object model (as in `vision track`).
    pub model: Option<&'a str>,
    /// The YCB-Video class of directory inputs.
    pub object: Option<&'a str>,
    /// Where masks and poses come from.
    pub measurements: Measurements,
    /// How the tracker starts.
    pub init: TrackerStart,
}

/// The tracker of `options` scored on each input, and on all of them
/// together when there are several.
pub fn inputs(options: &InputEvalOptions<'_>) -> Result<Vec<ScoreRow>> {
    let model = options.model.context("--input needs --model (a file, or `sim` for simulated sessions)")?;
    let mut rows = Vec::new();
    let mut all = Vec::new();
    for input in options.inputs {
        let input_options = InputOptions {
            model,
            model_scale: 1.0,
            object: options.object,
            measurements: options.measurements,
            init: options.init,
            recover: false,
            aruco_config: None,
            external: None,
        };
        let Prepared { mut source, mut measurements, model, intrinsics, initial_pose } =
            prepare(input, &input_options)?;
        let settings = TrackerSettings { initial_pose, ..TrackerSettings::default() };
        let mut tracker = build_tracker(options.kind, &model, &intrinsics, &settings)?;
        let frames = track(source.as_mut(), measurements.as_mut(), Some(tracker.as_mut()), |_, _| {})?;
        anyhow::ensure!(!frames.is_empty(), "{}: no frame has a true pose to score against", input.display());
        let first = frames.iter().position(|f| f.estimate.is_some()).unwrap_or(0);
        let e = errors(&frames, first, Scored::Tracker, &*model.object_points()?);
        rows.push(ScoreRow { label: input.display().to_string(), metrics: summarize(&e) });
        all.extend(e);
    }
    if options.inputs.len() > 1 {
        rows.push(ScoreRow { label: "ALL".into(), metrics: summarize(&all) });
    }
    Ok(rows)
}
