//! Labelling sessions with the marker's ground truth (`label`): the
//! smoother's parameters and the in-hand options from their settings, and
//! the motion in the hand estimated jointly over several sessions.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion};
use slidetrack_calibration::ground_truth::{DEFAULT_GATE_MAHALANOBIS2, default_params, gate, thesis_params};
use slidetrack_calibration::in_hand::session::in_hand_jointly;
use slidetrack_calibration::in_hand::{ContactSource, InHandOptions};
use slidetrack_calibration::label::read_inputs;
use slidetrack_session::ReadOptions;

pub use slidetrack_calibration::ground_truth::AxisSource;
pub use slidetrack_calibration::hand_frame::{HandCalibrationFile, HandFrame};
pub use slidetrack_calibration::in_hand::InHandRecord;
pub use slidetrack_calibration::in_hand::hold::DEFAULT_SETTLE_S;
pub use slidetrack_calibration::label::{
    GroundTruthSlot, JointTuning, LabelOptions, LabelReport, Tuning, label_session, tune_sessions,
};
pub use slidetrack_estimators::constant_velocity::CvParams;
pub use slidetrack_estimators::slip::DEFAULT_CONTACT_LOAD_COUNTS;

/// The marker smoother's parameters as asked for: the defaults (or the
/// thesis's) with overrides.
#[derive(Clone, Debug, Default)]
pub struct SmootherSettings {
    /// Start from the thesis's parameters instead of the defaults.
    pub thesis: bool,
    /// Spectral density of the position random walk (m^2/s).
    pub q_position: Option<f64>,
    /// Spectral density of the velocity random walk (m^2/s^3).
    pub q_velocity: Option<f64>,
    /// Variance of a marker position (m^2).
    pub r: Option<f64>,
    /// The innovation gate (squared Mahalanobis distance).
    pub gate: Option<f64>,
    /// No innovation gate.
    pub no_gate: bool,
    /// The parameters will be tuned (with a gate, the default one if none).
    pub tune: bool,
    /// Re-acquire after this many rejected positions in a row (0: never).
    pub reacquire_after: u32,
}

/// The defaults with the overrides of `s`, checked.
pub fn smoother_params(s: &SmootherSettings) -> Result<CvParams> {
    let mut p = if s.thesis { thesis_params() } else { default_params() };
    let positive = |name: &str, v: f64| -> Result<f64> {
        if v.is_finite() && v > 0.0 { Ok(v) } else { bail!("--{name} must be a positive number, got {v}") }
    };
    if let Some(q) = s.q_position {
        p.q_position_m2_per_s = positive("q-position", q)?;
    }
    if let Some(q) = s.q_velocity {
        p.q_velocity_m2_per_s3 = positive("q-velocity", q)?;
    }
    if let Some(r) = s.r {
        p.r_m2 = positive("r", r)?;
    }
    if let Some(g) = s.gate {
        p.gate = gate(Some(positive("gate", g)?));
    }
    if s.no_gate {
        p.gate = None;
    }
    if s.tune && p.gate.is_none() {
        // Without a gate the likelihood has optima that follow every marker
        // position exactly (R -> 0, a noisy velocity): tune with the default gate.
        p.gate = gate(Some(DEFAULT_GATE_MAHALANOBIS2));
    }
    if let Some(g) = p.gate.as_mut() {
        g.reacquire_after = (s.reacquire_after > 0).then_some(s.reacquire_after);
    }
    Ok(p)
}

/// How to label the motion in the hand.
#[derive(Clone, Debug, Default)]
pub struct InHandSettings<'a> {
    /// Do not label it.
    pub off: bool,
    /// The pose smoother's parameters and contact frame of this file
    /// (written by a joint labelling), instead of tuned and estimated ones.
    pub from_file: Option<&'a Path>,
    /// Re-acquire after this many rejected poses in a row (0: never).
    pub reacquire_after: u32,
    /// The camera's pose in the hand frame: `X,Y,Z,QX,QY,QZ,QW` (m, quaternion).
    pub hand_from_camera: Option<&'a [f64]>,
    /// The normal load at which the hold begins (counts).
    pub contact_load_counts: f64,
    /// Time after the contact load before the hold counts (s).
    pub hold_settle_s: f64,
    /// The hold runs from the first scan with a marker pose to the last.
    pub hold_from_start: bool,
}

/// The in-hand labelling of `s` (`None` when off).
pub fn in_hand_options(s: &InHandSettings<'_>) -> Result<Option<InHandOptions>> {
    if s.off {
        return Ok(None);
    }
    let mut o = InHandOptions::default();
    if let Some(path) = s.from_file {
        let text =
            std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
        let record: InHandRecord = serde_json::from_str(&text)
            .with_context(|| format!("{}: not a --save-in-hand file", path.display()))?;
        o.params = (&record.pose).into();
        o.contact = ContactSource::Given(record.contact);
    }
    if let Some(g) = o.params.gate.as_mut() {
        g.reacquire_after = (s.reacquire_after > 0).then_some(s.reacquire_after);
    }
    if let Some(v) = s.hand_from_camera {
        let q =
            UnitQuaternion::try_new(Quaternion::new(v[6], v[3], v[4], v[5]), 1e-9).with_context(|| {
                format!("--hand-from-camera: the quaternion {:?} has no usable norm", &v[3..])
            })?;
        o.hand_from_camera = Some(Isometry3::from_parts(Translation3::new(v[0], v[1], v[2]), q));
    }
    if !(s.contact_load_counts.is_finite() && s.contact_load_counts > 0.0) {
        bail!("--contact-load must be a positive number of counts, got {}", s.contact_load_counts);
    }
    if !(s.hold_settle_s.is_finite() && s.hold_settle_s >= 0.0) {
        bail!("--hold-settle must be a non-negative number of seconds, got {}", s.hold_settle_s);
    }
    o.hold.detector.contact_load_counts = s.contact_load_counts;
    o.hold.settle_s = s.hold_settle_s;
    o.hold.from_start = s.hold_from_start;
    Ok(Some(o))
}

/// The hand calibration at `path` (`calibrate hand --out`), checked;
/// `None` without one.
pub fn hand_calibration(path: Option<&Path>) -> Result<Option<HandCalibrationFile>> {
    path.map(HandCalibrationFile::load).transpose().context("label --hand-calibration")
}

/// The pose smoother's densities tuned on all of `files` and the contact
/// frame estimated from all their holds, put into `options`; `None`
/// without in-hand labelling or without a hold.
pub fn in_hand_jointly_into(
    files: &[PathBuf],
    recover: bool,
    options: &mut LabelOptions,
) -> Result<Option<InHandRecord>> {
    let Some(o) = options.in_hand.as_mut() else { return Ok(None) };
    let read = ReadOptions { recover };
    let inputs = files.iter().map(|f| read_inputs(f, read)).collect::<Result<Vec<_>, _>>()?;
    if let Some(file) = &options.hand {
        // The calibrated camera pose, and the geometry's contact frame (of
        // the first session's rig configuration unless the file has one).
        let frame = file.hand_frame(inputs.first().and_then(|i| i.rig_config.as_deref()))?;
        *o = frame.in_hand_options(o);
    }
    let Some(record) = in_hand_jointly(&inputs, o, true)? else { return Ok(None) };
    o.params = (&record.pose).into();
    o.contact = ContactSource::Given(record.contact.clone());
    options.in_hand_joint = Some(record.how.clone());
    Ok(Some(record))
}
