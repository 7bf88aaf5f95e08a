//! Labelling a session: read its marker detections and tactile scan times,
//! build the ground truth ([`crate::ground_truth`]) and write it into the
//! file as `/ground_truth/sliding` and `/ground_truth/measurements` (or,
//! for a second ground truth kept beside the first, under
//! `/ground_truth/thesis/`: [`GroundTruthSlot`]), rewriting the file
//! atomically (every other record unchanged).

use std::path::{Path, PathBuf};

use slidetrack_estimators::constant_velocity::tune::{
    TunedNoise, log_likelihood, tune_noise, tune_noise_jointly,
};
use slidetrack_estimators::constant_velocity::{CvParams, CvSample};
use slidetrack_session::{
    ChannelMessage, GroundTruthMeasurement, GroundTruthPlanar, GroundTruthPose, GroundTruthSliding,
    NewChannel, ReadOptions, SessionError, rewrite_session,
};
use thiserror::Error;

use crate::ground_truth::{
    AxisSource, GroundTruth, GroundTruthError, Measurements, Rmse, marker_positions,
    marker_positions_on_axis, parameters_record, rmse_against_truth, smooth_ground_truth,
};
use crate::hand_frame::{HandCalibrationFile, HandFrame};
use crate::in_hand::session::{InHandLabel, in_hand_channels, label_in_hand};
use crate::in_hand::{ContactFrame, InHandOptions, PoseParamsRecord};
pub use crate::session_inputs::{SessionInputs, read_inputs};

/// How to label.
#[derive(Clone, Debug, PartialEq)]
pub struct LabelOptions {
    /// The smoother's parameters.
    pub params: CvParams,
    /// Where the positions along the axis come from (without `hand`).
    pub axis: AxisSource,
    /// A hand calibration: the marker's positions and poses are moved into
    /// the hand frame with its camera pose, the sliding axis and the contact
    /// frame come from the hand's geometry ([`crate::hand_frame`]), and
    /// `axis` is not used.
    pub hand: Option<HandCalibrationFile>,
    /// Label a truncated file (its complete chunks; the rewritten file is complete).
    pub recover: bool,
    /// Compute and report, but do not write the file.
    pub dry_run: bool,
    /// Whether `params` are used as given, tuned on the session, or were
    /// tuned over several sessions ([`tune_sessions`]).
    pub tuning: Tuning,
    /// The channels written (and replaced).
    pub slot: GroundTruthSlot,
    /// Also label the motion in the hand (`/ground_truth/pose`,
    /// `/ground_truth/planar`) when the detections carry poses and the slot
    /// is the default one; `None`: not.
    pub in_hand: Option<InHandOptions>,
    /// How the in-hand parameters were found when they were estimated over
    /// several sessions ([`crate::in_hand::session::in_hand_jointly`]), in
    /// words; `None`: given or tuned here.
    pub in_hand_joint: Option<String>,
}

/// Where the smoother's noise parameters come from.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum Tuning {
    /// `LabelOptions::params` as given.
    #[default]
    Off,
    /// `q_p`, `q_v` and `R` estimated from the session's own marker
    /// positions (maximum likelihood, starting from `params`).
    PerSession,
    /// `params` are the estimate of [`tune_sessions`] over several
    /// sessions; the labelling records how it was made.
    Joint(JointTuning),
}

/// How [`tune_sessions`] estimated one set of parameters for several sessions.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct JointTuning {
    /// The parameters the search started from.
    pub start: CvParams,
    /// Sessions whose marker positions were used.
    pub sessions: usize,
    /// Marker positions used, over all sessions.
    pub measurements: usize,
    /// The summed log-likelihood of those positions at the estimate.
    pub log_likelihood: f64,
    /// Likelihood evaluations of the search.
    pub evaluations: usize,
}

/// The pair of channels a labelling writes. A session can hold one ground
/// truth per slot: labelling replaces the two channels of its own slot and
/// keeps every other, so that the default protocol's ground truth and the
/// thesis protocol's (`slidetrack study --protocol`) live side by side.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum GroundTruthSlot {
    /// `/ground_truth/sliding` and `/ground_truth/measurements`, what
    /// `train`, `eval`, `replay` and the plots read.
    #[default]
    Default,
    /// `/ground_truth/thesis/sliding` and `/ground_truth/thesis/measurements`
    /// (same messages and metadata).
    Thesis,
}

impl GroundTruthSlot {
    /// The topic of the smoothed state.
    pub const fn sliding_topic(self) -> &'static str {
        match self {
            GroundTruthSlot::Default => GroundTruthSliding::TOPIC,
            GroundTruthSlot::Thesis => "/ground_truth/thesis/sliding",
        }
    }

    /// The topic of the marker positions used.
    pub const fn measurements_topic(self) -> &'static str {
        match self {
            GroundTruthSlot::Default => GroundTruthMeasurement::TOPIC,
            GroundTruthSlot::Thesis => "/ground_truth/thesis/measurements",
        }
    }
}

/// What a labelling did.
#[derive(Clone, Debug, PartialEq)]
pub struct LabelReport {
    /// The session file.
    pub path: PathBuf,
    /// Tactile scans labelled (messages on `/ground_truth/sliding`).
    pub samples: usize,
    /// Camera frames.
    pub frames: usize,
    /// Camera frames with a marker position.
    pub detections: usize,
    /// Camera frames without one.
    pub missing_detections: usize,
    /// Marker positions the innovation gate rejected.
    pub rejected_outliers: usize,
    /// Against `/sim/truth` (when the session has it), from the first marker
    /// position to the release of the hand.
    pub rmse: Option<Rmse>,
    /// The sliding direction in the camera frame, when computed here.
    pub axis_in_camera: Option<[f64; 3]>,
    /// The file was written (false for a dry run).
    pub written: bool,
    /// The smoother's parameters used (tuned ones when tuning).
    pub params: CvParams,
    /// `params` were tuned (on this session or over several).
    pub tuned: bool,
    /// The log-likelihood of this session's marker positions at `params`
    /// (the gated form of [`log_likelihood`]): compare parameter choices on
    /// sessions they were not tuned on by it, without a true trajectory.
    pub log_likelihood: f64,
    /// The motion in the hand, when it was labelled.
    pub in_hand: Option<InHandSummary>,
    /// The hand frame used, with a hand calibration.
    pub hand_frame: Option<HandFrame>,
    /// Where the positions along the sliding axis came from, in words.
    pub axis_from: String,
}

/// What the in-hand labelling of a session found.
#[derive(Clone, Debug, PartialEq)]
pub struct InHandSummary {
    /// Scans with a pose (from the marker's first sighting to its last).
    pub poses: usize,
    /// Marker poses measured.
    pub measured: usize,
    /// Marker poses the gate rejected.
    pub rejected: usize,
    /// The log-likelihood of the marker poses at the parameters used.
    pub log_likelihood: f64,
    /// Scans of the hold (with a planar state).
    pub hold_scans: usize,
    /// The pose smoother's parameters used.
    pub params: PoseParamsRecord,
    /// The contact frame used.
    pub contact: Option<ContactFrame>,
}

/// Why a session could not be labelled. The file is unchanged in every case.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum LabelError {
    /// Reading or rewriting the file failed.
    #[error(transparent)]
    Session(#[from] SessionError),
    /// The session has no `/aruco/detections` channel (recorded without camera).
    #[error("{path} has no marker detections (/aruco/detections): it was recorded without a camera")]
    NoCamera {
        /// The file.
        path: PathBuf,
    },
    /// The ground truth could not be built.
    #[error("{path}: {source}")]
    GroundTruth {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: GroundTruthError,
    },
    /// A message could not be encoded.
    #[error("{path}: cannot encode the ground truth: {source}")]
    Encode {
        /// The file.
        path: PathBuf,
        /// The encoder's error.
        #[source]
        source: serde_json::Error,
    },
}

/// The marker positions of `measurements` as the smoother's samples, time
/// 0 at the first.
fn marker_samples(measurements: &Measurements) -> Vec<CvSample> {
    let t0 = measurements.positions.first().map_or(0, |p| p.0.0);
    measurements
        .positions
        .iter()
        .map(|(t, z)| CvSample { t_s: (t.0 - t0) as f64 * 1e-9, z_m: Some(*z) })
        .collect()
}

/// The parameters a labelling smoothed with, and how well they fit its
/// marker positions.
#[derive(Clone, Debug, PartialEq)]
pub struct Fit {
    /// The smoother's parameters used.
    pub params: CvParams,
    /// The log-likelihood of the session's marker positions at `params`.
    pub log_likelihood: f64,
    /// With [`Tuning::PerSession`]: how `params` were found.
    pub tuned: Option<TunedNoise>,
}

/// The marker positions of a session along the sliding axis, `None` when
/// it was recorded without a camera.
fn marker_measurements(
    inputs: &SessionInputs,
    options: &LabelOptions,
) -> Result<Option<Measurements>, GroundTruthError> {
    let Some(detections) = &inputs.detections else { return Ok(None) };
    match hand_frame(inputs, options)? {
        Some(frame) => {
            marker_positions_on_axis(detections, &frame.sliding_axis(), frame.axis_source()).map(Some)
        }
        None => marker_positions(detections, options.axis, inputs.rig_config.as_deref()).map(Some),
    }
}

/// The hand frame of `inputs` with `options.hand` (its geometry may come
/// from the session's rig configuration), `None` without a hand calibration.
pub fn hand_frame(
    inputs: &SessionInputs,
    options: &LabelOptions,
) -> Result<Option<HandFrame>, GroundTruthError> {
    let Some(file) = &options.hand else { return Ok(None) };
    file.hand_frame(inputs.rig_config.as_deref())
        .map(Some)
        .map_err(|e| GroundTruthError::RigConfig { detail: e.to_string() })
}

/// The ground truth of `inputs`, and the parameters it was smoothed with
/// (tuned on the marker positions with [`Tuning::PerSession`], as given
/// otherwise).
pub fn compute(
    inputs: &SessionInputs,
    options: &LabelOptions,
) -> Result<Option<(Measurements, GroundTruth, Fit)>, GroundTruthError> {
    let Some(measurements) = marker_measurements(inputs, options)? else { return Ok(None) };
    let samples = marker_samples(&measurements);
    let fit = match options.tuning {
        Tuning::PerSession => {
            let t = tune_noise(&options.params, &samples);
            Fit { params: t.params, log_likelihood: t.log_likelihood, tuned: Some(t) }
        }
        Tuning::Off | Tuning::Joint(_) => Fit {
            params: options.params,
            log_likelihood: log_likelihood(&options.params, &samples),
            tuned: None,
        },
    };
    let gt = smooth_ground_truth(&inputs.scans, &measurements.positions, &fit.params)?;
    Ok(Some((measurements, gt, fit)))
}

/// One set of `q_p`, `q_v` and `R` for all the sessions at `paths` (one rig
/// and marker), maximising the summed likelihood of their marker positions
/// from `options.params`; label each with [`Tuning::Joint`] and the
/// returned parameters. Sessions are read, not written.
pub fn tune_sessions(
    paths: &[PathBuf],
    options: &LabelOptions,
) -> Result<(CvParams, JointTuning), LabelError> {
    let read = ReadOptions { recover: options.recover };
    let mut sequences = Vec::with_capacity(paths.len());
    for path in paths {
        let measurements = marker_measurements(&read_inputs(path, read)?, options)
            .map_err(|source| LabelError::GroundTruth { path: path.to_path_buf(), source })?
            .ok_or_else(|| LabelError::NoCamera { path: path.to_path_buf() })?;
        sequences.push(marker_samples(&measurements));
    }
    let slices: Vec<&[CvSample]> = sequences.iter().map(Vec::as_slice).collect();
    let tuned = tune_noise_jointly(&options.params, &slices);
    let joint = JointTuning {
        start: options.params,
        sessions: paths.len(),
        measurements: tuned.measurements,
        log_likelihood: tuned.log_likelihood,
        evaluations: tuned.evaluations,
    };
    Ok((tuned.params, joint))
}

/// How the parameters of a labelling were tuned, in words, for the channel
/// metadata (`None` when they were given).
fn tuning_record(options: &LabelOptions, tuned: Option<&TunedNoise>, report: &LabelReport) -> Option<String> {
    match (options.tuning, tuned) {
        (Tuning::Joint(j), _) => Some(format!(
            "q_position_m2_per_s, q_velocity_m2_per_s3 and r_m2 estimated jointly from the {} marker positions of \
             {} sessions (this one's {}) by maximum marginal likelihood (Kalman filter innovations, each session \
             filtered from x0 and p0; a gated position counts at the gate's edge), Nelder-Mead on their logarithms \
             from q_p = {:e}, q_v = {:e}, R = {:e}: summed log-likelihood {:.3} after {} evaluations; this \
             session's {:.3}",
            j.measurements,
            j.sessions,
            report.detections,
            j.start.q_position_m2_per_s,
            j.start.q_velocity_m2_per_s3,
            j.start.r_m2,
            j.log_likelihood,
            j.evaluations,
            report.log_likelihood,
        )),
        (_, Some(t)) => Some(format!(
            "q_position_m2_per_s, q_velocity_m2_per_s3 and r_m2 estimated from the {} marker positions by maximum \
             marginal likelihood (Kalman filter innovations; a gated position counts at the gate's edge), \
             Nelder-Mead on their logarithms from q_p = {:e}, q_v = {:e}, R = {:e}: log-likelihood {:.3} after {} \
             evaluations",
            t.measurements,
            options.params.q_position_m2_per_s,
            options.params.q_velocity_m2_per_s3,
            options.params.r_m2,
            t.log_likelihood,
            t.evaluations
        )),
        (_, None) => None,
    }
}

/// The motion in the hand of `inputs` when `options` ask for it (default
/// slot only), in the hand frame of `hand` when given (its camera pose and
/// contact frame).
fn in_hand_of(
    inputs: &SessionInputs,
    options: &LabelOptions,
    hand: Option<&HandFrame>,
) -> Result<Option<InHandLabel>, GroundTruthError> {
    let (Some(o), GroundTruthSlot::Default) = (&options.in_hand, options.slot) else { return Ok(None) };
    let o = hand.map_or_else(|| o.clone(), |frame| frame.in_hand_options(o));
    Ok(label_in_hand(inputs, &o, options.tuning == Tuning::PerSession)?)
}

/// Labels the session at `path`: see the module documentation.
pub fn label_session(path: &Path, options: &LabelOptions) -> Result<LabelReport, LabelError> {
    let read = ReadOptions { recover: options.recover };
    let inputs = read_inputs(path, read)?;
    let gt_err = |source| LabelError::GroundTruth { path: path.to_path_buf(), source };
    let (measurements, gt, fit) = compute(&inputs, options)
        .map_err(gt_err)?
        .ok_or_else(|| LabelError::NoCamera { path: path.to_path_buf() })?;
    let sliding = gt.sliding();
    let used = gt.measurements();
    let rmse = match (used.first(), used.last()) {
        (Some(first), Some(last)) if !inputs.truth.is_empty() => {
            let until = inputs.release.map_or(last.0, |r| r.min(last.0));
            rmse_against_truth(&sliding, &inputs.truth, first.0, until)
        }
        _ => None,
    };
    let mut report = LabelReport {
        path: path.to_path_buf(),
        samples: sliding.len(),
        frames: measurements.frames,
        detections: measurements.positions.len(),
        missing_detections: measurements.missing,
        rejected_outliers: gt.rejected(),
        rmse,
        axis_in_camera: measurements.axis_in_camera.map(|a| [a.x, a.y, a.z]),
        written: false,
        params: fit.params,
        tuned: options.tuning != Tuning::Off,
        log_likelihood: fit.log_likelihood,
        in_hand: None,
        hand_frame: hand_frame(&inputs, options).map_err(gt_err)?,
        axis_from: measurements.source.clone(),
    };
    let in_hand = in_hand_of(&inputs, options, report.hand_frame.as_ref()).map_err(gt_err)?;
    report.in_hand = in_hand.as_ref().map(|l| InHandSummary {
        poses: l.session.track.scans.len(),
        measured: l.session.track.measured,
        rejected: l.session.track.rejected,
        log_likelihood: l.session.track.log_likelihood,
        hold_scans: l.planar.len(),
        params: PoseParamsRecord::from(&l.params),
        contact: l.frame.clone(),
    });
    if options.dry_run {
        return Ok(report);
    }
    let mut record = parameters_record(&report.params, &measurements);
    record.tuning = tuning_record(options, fit.tuned.as_ref(), &report);
    let metadata = record.channel_metadata();
    let encode = |source| LabelError::Encode { path: path.to_path_buf(), source };
    let mut sliding_channel = NewChannel::of::<GroundTruthSliding>(metadata.clone());
    sliding_channel.topic = options.slot.sliding_topic().to_string();
    for (t, m) in &sliding {
        sliding_channel.push_json(*t, m).map_err(encode)?;
    }
    let mut measurement_channel = NewChannel::of::<GroundTruthMeasurement>(metadata);
    measurement_channel.topic = options.slot.measurements_topic().to_string();
    for (t, m) in &used {
        measurement_channel.push_json(*t, m).map_err(encode)?;
    }
    let mut channels = vec![sliding_channel, measurement_channel];
    if let Some(l) = &in_hand {
        let how = options.in_hand_joint.clone().unwrap_or_else(|| l.how.clone());
        channels.extend(in_hand_channels(l, &how).map_err(encode)?);
    }
    // Only this slot's channels: the other slot's ground truth stays; the
    // in-hand channels are the default slot's.
    let slot = options.slot;
    let in_hand_topics = [GroundTruthPose::TOPIC, GroundTruthPlanar::TOPIC];
    let replaced = |topic: &str| {
        topic == slot.sliding_topic()
            || topic == slot.measurements_topic()
            || (slot == GroundTruthSlot::Default
                && options.in_hand.is_some()
                && in_hand_topics.contains(&topic))
    };
    rewrite_session(path, read, &replaced, channels)?;
    report.written = true;
    Ok(report)
}
