//! The motion in the hand of one session, or of several labelled together:
//! what `label` computes and the channels it writes.

use nalgebra::{Isometry3, Vector3};
use slidetrack_core::TimeNs;
use slidetrack_estimators::EstimatorError;
use slidetrack_estimators::pose_smoother::{PoseSample, PoseSmootherParams, tune_pose_noise};
use slidetrack_session::{GroundTruthPlanar, GroundTruthPose, NewChannel, PlanarState};

use super::hold::HoldInputs;
use super::planar::DEFAULT_MAX_GAP_S;
use super::pose::{hand_poses, pose_message, samples};
use super::{
    ContactFrame, ContactSource, Hold, InHandOptions, InHandRecord, PoseParamsRecord, PoseTrack,
    estimate_contact_frame, find_hold, planar_states, pose_track,
};
use crate::ground_truth::axis_from_rig_config;
use crate::session_inputs::SessionInputs;

/// Channel metadata key of `/ground_truth/pose` and `/ground_truth/planar`
/// holding how they were made (JSON).
pub const IN_HAND_METADATA_KEY: &str = "in_hand";

/// The default normal hint: the hand frame's x axis. On the imanlab rigs
/// (hand frame = the wrist camera's) the measured closing axis lies a few
/// degrees from it; on the simulated rig it points at the camera.
pub const NORMAL_HINT: [f64; 3] = [1.0, 0.0, 0.0];

/// The x-axis hint without a rig configuration: the hand frame's y axis.
pub const X_HINT: [f64; 3] = [0.0, 1.0, 0.0];

/// The camera's pose in the hand: as given, else the rig configuration's
/// placement, else the identity (a camera riding on the hand).
pub fn hand_from_camera(options: &InHandOptions, rig_config: Option<&str>) -> Isometry3<f64> {
    options.hand_from_camera.unwrap_or_else(|| {
        rig_config
            .and_then(|t| axis_from_rig_config(t).ok())
            .map_or_else(Isometry3::identity, |a| a.hand_from_camera)
    })
}

/// The hints of the contact frame: the normal's, and the x axis's (the
/// rig's sliding axis when it has one).
fn hints(rig_config: Option<&str>) -> (Vector3<f64>, Vector3<f64>) {
    let x = rig_config
        .and_then(|t| axis_from_rig_config(t).ok())
        .map_or(Vector3::from(X_HINT), |a| a.axis_in_hand.into_inner());
    (Vector3::from(NORMAL_HINT), x)
}

/// A session's pose track and hold.
pub struct TrackedSession {
    /// The smoothed pose at the scans from the first sighting to the last.
    pub track: PoseTrack,
    /// The hold among `track.scans`, when there is one.
    pub hold: Option<Hold>,
}

/// The pose track and the hold of `inputs` with `params`; `Ok(None)` when
/// no marker detection carries a pose.
pub fn track_session(
    inputs: &SessionInputs,
    options: &InHandOptions,
    params: &PoseSmootherParams,
) -> Result<Option<TrackedSession>, EstimatorError> {
    let Some(detections) = &inputs.detections else { return Ok(None) };
    let hand = hand_from_camera(options, inputs.rig_config.as_deref());
    let Some(track) = pose_track(&inputs.scans, detections, hand, params)? else { return Ok(None) };
    let hold = find_hold(
        &HoldInputs {
            scans: &track.scans,
            loads: &inputs.loads,
            cycles: inputs.cycles,
            release: inputs.release,
        },
        &options.hold,
    );
    Ok(Some(TrackedSession { track, hold }))
}

/// The smoother's samples of a session (for tuning).
pub fn pose_samples(inputs: &SessionInputs, options: &InHandOptions) -> Vec<PoseSample> {
    let Some(detections) = &inputs.detections else { return Vec::new() };
    let hand = hand_from_camera(options, inputs.rig_config.as_deref());
    let poses = hand_poses(detections, &hand);
    let (Some(first), Some(last)) = (poses.first(), poses.last()) else { return Vec::new() };
    let scans: Vec<TimeNs> = inputs.scans.iter().copied().filter(|t| *t >= first.0 && *t <= last.0).collect();
    samples(&scans, &poses).samples
}

/// The motion in the hand of one session, as labelled.
pub struct InHandLabel {
    /// The pose track and hold.
    pub session: TrackedSession,
    /// The pose smoother's parameters used.
    pub params: PoseSmootherParams,
    /// The contact frame (with a hold).
    pub frame: Option<ContactFrame>,
    /// The planar state at the scans of the hold.
    pub planar: Vec<(TimeNs, PlanarState)>,
    /// How the parameters were found, in words.
    pub how: String,
}

/// Labels the motion in the hand of `inputs`: `params` tuned on the
/// session with `tune`, the contact frame as `options` says (estimated from
/// this session alone when not given). `Ok(None)` without marker poses.
pub fn label_in_hand(
    inputs: &SessionInputs,
    options: &InHandOptions,
    tune: bool,
) -> Result<Option<InHandLabel>, EstimatorError> {
    let (params, how) = if tune {
        let samples = pose_samples(inputs, options);
        let t = tune_pose_noise(&options.params, &[&samples]);
        let how = format!(
            "the six densities estimated from this session's {} marker poses by maximum likelihood \
             (log-likelihood {:.1} after {} evaluations)",
            t.measurements, t.log_likelihood, t.evaluations
        );
        (t.params, how)
    } else {
        (options.params, "as given".to_string())
    };
    let Some(session) = track_session(inputs, options, &params)? else { return Ok(None) };
    let frame = match (&options.contact, &session.hold) {
        (ContactSource::Given(f), _) => Some(f.clone()),
        (ContactSource::Estimate, Some(hold)) => {
            let (n, x) = hints(inputs.rig_config.as_deref());
            estimate_contact_frame(&[(&session.track, hold)], n, x)
        }
        (ContactSource::Estimate, None) => None,
    };
    let planar = match (&frame, &session.hold) {
        (Some(f), Some(h)) => planar_states(&session.track, h, f, DEFAULT_MAX_GAP_S),
        _ => Vec::new(),
    };
    Ok(Some(InHandLabel { session, params, frame, planar, how }))
}

/// One pose smoother and one contact frame for several sessions: the
/// densities tuned on all their marker poses together (with `tune`, else
/// as given), the frame estimated from all their holds.
pub fn in_hand_jointly(
    sessions: &[SessionInputs],
    options: &InHandOptions,
    tune: bool,
) -> Result<Option<InHandRecord>, EstimatorError> {
    let (params, how) = if tune {
        let samples: Vec<Vec<PoseSample>> = sessions.iter().map(|s| pose_samples(s, options)).collect();
        let slices: Vec<&[PoseSample]> = samples.iter().map(Vec::as_slice).collect();
        let t = tune_pose_noise(&options.params, &slices);
        let how = format!(
            "the six densities estimated jointly from the {} marker poses of {} sessions by maximum likelihood \
             (summed log-likelihood {:.1} after {} evaluations)",
            t.measurements,
            sessions.len(),
            t.log_likelihood,
            t.evaluations
        );
        (t.params, how)
    } else {
        (options.params, "pose smoother parameters as given".to_string())
    };
    let mut tracked = Vec::new();
    for s in sessions {
        if let Some(t) = track_session(s, options, &params)? {
            tracked.push(t);
        }
    }
    let holds: Vec<(&PoseTrack, &Hold)> =
        tracked.iter().filter_map(|t| Some((&t.track, t.hold.as_ref()?))).collect();
    let (n, x) = hints(sessions.first().and_then(|s| s.rig_config.as_deref()));
    let frame = match &options.contact {
        ContactSource::Given(f) => Some(f.clone()),
        ContactSource::Estimate => estimate_contact_frame(&holds, n, x),
    };
    Ok(frame.map(|contact| InHandRecord {
        pose: PoseParamsRecord::from(&params),
        contact,
        how: format!("{how}; contact frame from the holds of {} of {} sessions", holds.len(), sessions.len()),
    }))
}

/// The `/ground_truth/pose` and `/ground_truth/planar` channels of `label`,
/// with `how` (JSON) in their metadata.
pub fn in_hand_channels(label: &InHandLabel, tuning: &str) -> Result<Vec<NewChannel>, serde_json::Error> {
    let s = &label.session;
    let t0 = s.track.scans.first().copied().unwrap_or(TimeNs(0));
    let meta = serde_json::json!({
        "pose_smoother": PoseParamsRecord::from(&label.params),
        "pose_tuning": tuning,
        "hand_from_camera": {
            "translation_m": s.track.hand_from_camera.translation.vector.as_slice(),
            "quaternion_xyzw": s.track.hand_from_camera.rotation.coords.as_slice(),
        },
        "marker_poses": s.track.measured,
        "rejected_poses": s.track.rejected,
        "log_likelihood": s.track.log_likelihood,
        "contact": label.frame,
        "hold": s.hold.as_ref().map(|h| serde_json::json!({
            "start_s": s.track.scans[h.start].secs_since(t0),
            "end_s": s.track.scans[h.end - 1].secs_since(t0),
            "scans": h.end - h.start,
            "how": h.how,
        })),
        "time_origin": "the marker's first sighting",
        "planar_gaps": format!(
            "the planar state is left out at scans inside a gap of more than {DEFAULT_MAX_GAP_S} s between two marker \
             poses the smoother used (the pose there is the motion model's guess)"
        ),
    });
    let metadata =
        std::collections::BTreeMap::from([(IN_HAND_METADATA_KEY.to_string(), serde_json::to_string(&meta)?)]);
    let mut pose = NewChannel::of::<GroundTruthPose>(metadata.clone());
    for (t, p) in s.track.scans.iter().zip(&s.track.poses) {
        pose.push_json(*t, &pose_message(p))?;
    }
    let mut channels = vec![pose];
    if !label.planar.is_empty() {
        let mut planar = NewChannel::of::<GroundTruthPlanar>(metadata);
        for (t, state) in &label.planar {
            planar.push_json(*t, &GroundTruthPlanar(*state))?;
        }
        channels.push(planar);
    }
    Ok(channels)
}
