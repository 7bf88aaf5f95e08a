//! The object's motion in the hand from the marker's poses: the pose ground
//! truth (`/ground_truth/pose`) and the planar slip in the contact plane of
//! a parallel gripper (`/ground_truth/planar`), written by `slidetrack label`
//! beside the sliding ground truth.
//!
//! 1. **Pose in the hand** ([`pose`]): every marker pose of
//!    `/aruco/detections` moved into the hand frame (`hand_from_camera`:
//!    identity where the camera rides on the hand, as on the imanlab rigs;
//!    the rig configuration's camera placement on a rig that has one; or
//!    given), smoothed with the constant-velocity RTS smoother on position
//!    and on the rotation group ([`slidetrack_estimators::pose_smoother`]),
//!    at every tactile scan from the marker's first sighting to its last.
//! 2. **The hold** ([`hold`]): the scans during which the object is held.
//!    On a protocol session, from the start of the sliding cycles to the
//!    release; on a recording without the protocol, from the first scan at
//!    which the normal load (sum of every taxel's baseline-subtracted z)
//!    reaches the grasp detector's contact level, plus a settling time, to
//!    the first scan the detector calls the object dropped or released.
//! 3. **The contact frame** ([`contact`]): its normal is the gripper's
//!    closing axis, found as the axis about which the held objects rotate
//!    (the principal axis of their rotation vectors relative to the hold's
//!    start); its origin, the grip point, is the point of the hand about
//!    which they pivot (least squares); its x axis the principal direction
//!    in which that point moves in the plane. Or given.
//! 4. **The planar state** ([`planar`]): at every scan of the hold, the
//!    displacement of the grip point (the object's point that was at the
//!    frame's origin at the hold's start) along x and y, the rotation about
//!    the normal (the twist of the relative rotation), and their rates.

pub mod contact;
pub mod hold;
pub mod planar;
pub mod pose;
pub mod session;

#[cfg(test)]
mod tests;

pub use contact::{ContactFrame, estimate_contact_frame};
pub use hold::{Hold, HoldOptions, find_hold};
pub use planar::planar_states;
pub use pose::{PoseTrack, pose_track};

use nalgebra::Isometry3;
use serde::{Deserialize, Serialize};
use slidetrack_estimators::pose_smoother::PoseSmootherParams;

/// Where the contact frame comes from.
#[derive(Clone, Debug, PartialEq)]
pub enum ContactSource {
    /// Estimated from the labelled sessions' held motion (one session alone,
    /// or all of them with `label --jointly`).
    Estimate,
    /// As given (`label --in-hand FILE`).
    Given(ContactFrame),
}

/// How to label the motion in the hand.
#[derive(Clone, Debug, PartialEq)]
pub struct InHandOptions {
    /// The pose smoother's parameters.
    pub params: PoseSmootherParams,
    /// The camera's pose in the hand frame; `None`: the rig configuration's
    /// camera placement when the session has one, else the identity (a
    /// camera riding on the hand).
    pub hand_from_camera: Option<Isometry3<f64>>,
    /// How the hold is found.
    pub hold: HoldOptions,
    /// Where the contact frame comes from.
    pub contact: ContactSource,
}

impl Default for InHandOptions {
    fn default() -> Self {
        InHandOptions {
            params: PoseSmootherParams::default(),
            hand_from_camera: None,
            hold: HoldOptions::default(),
            contact: ContactSource::Estimate,
        }
    }
}

/// The pose smoother's parameters as stored (`label --save-in-hand`) and in
/// the channel metadata: the six densities (SI units), the initial
/// variances and the gate.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PoseParamsRecord {
    /// Position random walk density per axis (m^2/s).
    pub q_position_m2_per_s: f64,
    /// Velocity random walk density per axis (m^2/s^3).
    pub q_velocity_m2_per_s3: f64,
    /// Position measurement variance per axis (m^2).
    pub r_position_m2: f64,
    /// Orientation random walk density per tangent axis (rad^2/s).
    pub q_orientation_rad2_per_s: f64,
    /// Angular-velocity random walk density per axis (rad^2/s^3).
    pub q_angular_velocity_rad2_per_s3: f64,
    /// Orientation measurement variance per tangent axis (rad^2).
    pub r_orientation_rad2: f64,
    /// Initial variances: position (m^2), velocity (m^2/s^2), orientation
    /// (rad^2), angular velocity (rad^2/s^2).
    pub p0: [f64; 4],
    /// The gate on the squared Mahalanobis distance of the 6-D pose
    /// innovation, `null` without one.
    pub gate_max_mahalanobis2: Option<f64>,
    /// Rejected poses in a row after which the gate opens (`null`: never).
    pub gate_reacquire_after: Option<u32>,
}

impl From<&PoseSmootherParams> for PoseParamsRecord {
    fn from(p: &PoseSmootherParams) -> Self {
        PoseParamsRecord {
            q_position_m2_per_s: p.q_position_m2_per_s,
            q_velocity_m2_per_s3: p.q_velocity_m2_per_s3,
            r_position_m2: p.r_position_m2,
            q_orientation_rad2_per_s: p.q_orientation_rad2_per_s,
            q_angular_velocity_rad2_per_s3: p.q_angular_velocity_rad2_per_s3,
            r_orientation_rad2: p.r_orientation_rad2,
            p0: [
                p.p0_position_m2,
                p.p0_velocity_m2_per_s2,
                p.p0_orientation_rad2,
                p.p0_angular_velocity_rad2_per_s2,
            ],
            gate_max_mahalanobis2: p.gate.map(|g| g.max_mahalanobis2),
            gate_reacquire_after: p.gate.and_then(|g| g.reacquire_after),
        }
    }
}

impl From<&PoseParamsRecord> for PoseSmootherParams {
    fn from(r: &PoseParamsRecord) -> Self {
        PoseSmootherParams {
            q_position_m2_per_s: r.q_position_m2_per_s,
            q_velocity_m2_per_s3: r.q_velocity_m2_per_s3,
            r_position_m2: r.r_position_m2,
            q_orientation_rad2_per_s: r.q_orientation_rad2_per_s,
            q_angular_velocity_rad2_per_s3: r.q_angular_velocity_rad2_per_s3,
            r_orientation_rad2: r.r_orientation_rad2,
            p0_position_m2: r.p0[0],
            p0_velocity_m2_per_s2: r.p0[1],
            p0_orientation_rad2: r.p0[2],
            p0_angular_velocity_rad2_per_s2: r.p0[3],
            gate: r.gate_max_mahalanobis2.map(|d2| slidetrack_estimators::rts::Gate {
                max_mahalanobis2: d2,
                reacquire_after: r.gate_reacquire_after,
            }),
        }
    }
}

/// What `label --save-in-hand` writes and `label --in-hand` reads: the
/// pose smoother's parameters and the contact frame estimated on some
/// sessions, to label others with (a test split with what the training
/// split gave).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InHandRecord {
    /// The pose smoother's parameters.
    pub pose: PoseParamsRecord,
    /// The contact frame.
    pub contact: ContactFrame,
    /// How they were found, in words.
    pub how: String,
}
