//! The channels of motion in the hand beyond one sliding axis: the object's
//! full pose relative to the hand (ground truth from the marker), its planar
//! slip in the contact plane of a parallel gripper (ground truth and the
//! planar dEKF's estimate), and the online grasp-state detector's output.
//!
//! Frames: `hand` is the frame the pose is expressed in (the camera's own
//! frame when the camera rides on the hand, as on both imanlab rigs; else the
//! camera frame moved by a configured `hand_from_camera`). The contact frame
//! of a parallel gripper has its z axis along the closing axis (the contact
//! normal) and its x and y axes in the contact plane; its origin is the grip
//! point. Both are given in `hand` in the channel metadata.

use serde::{Deserialize, Serialize};
use serde_json::Value;

use super::channel::ChannelMessage;
use super::schema::derived;
use super::vision::Quaternion;

/// `/ground_truth/pose`: the object's pose in the hand at one tactile scan,
/// from the marker's poses smoothed by a constant-velocity RTS smoother
/// (orientation on the rotation group).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct GroundTruthPose {
    /// The marker's (object's) origin in the hand frame (m).
    pub position_in_hand_m: [f64; 3],
    /// `hand_from_object` rotation.
    pub orientation_in_hand: Quaternion,
    /// Velocity of the object's origin in the hand frame (m/s).
    pub velocity_in_hand_m_per_s: [f64; 3],
    /// Angular velocity of the object in the hand frame (rad/s).
    pub angular_velocity_in_hand_rad_per_s: [f64; 3],
    /// Standard deviations of the smoothed state in the tangent space, in the
    /// order position (m, 3), velocity (m/s, 3), orientation (rad, 3, a
    /// rotation vector in the hand frame), angular velocity (rad/s, 3).
    pub std: [f64; 12],
}

impl ChannelMessage for GroundTruthPose {
    const TOPIC: &'static str = "/ground_truth/pose";
    const SCHEMA_NAME: &'static str = "slidetrack.GroundTruthPose";
    fn json_schema() -> Value {
        derived::<Self>(Self::SCHEMA_NAME)
    }
}

/// A planar slip state: the motion of the object in the contact plane since
/// the hold began.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct PlanarState {
    /// Translation of the grip point (the object's point that was at the
    /// contact frame's origin when the hold began) along the contact
    /// frame's x and y axes (m).
    pub translation_m: [f64; 2],
    /// Rotation about the contact normal (rad, right-handed about +z).
    pub rotation_rad: f64,
    /// Velocity of that point along x and y (m/s).
    pub velocity_m_per_s: [f64; 2],
    /// Angular velocity about the contact normal (rad/s).
    pub angular_velocity_rad_per_s: f64,
}

/// `/ground_truth/planar`: the planar slip state at one tactile scan, from
/// the hold's first scan (all zero there) to its end. The contact frame,
/// the hold's span and how both were found are in the channel metadata.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(transparent)]
pub struct GroundTruthPlanar(pub PlanarState);

impl ChannelMessage for GroundTruthPlanar {
    const TOPIC: &'static str = "/ground_truth/planar";
    const SCHEMA_NAME: &'static str = "slidetrack.PlanarState";
    fn json_schema() -> Value {
        derived::<Self>(Self::SCHEMA_NAME)
    }
}

/// `/estimate/dekf_planar`: the planar dEKF's estimate after a filter step.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct PlanarEstimate {
    /// The estimated state, 0 where the tracker started.
    pub state: PlanarState,
    /// Covariance of `(x, y, theta, vx, vy, omega)` (m, m, rad, m/s, m/s,
    /// rad/s), row-major, 36 values.
    pub covariance: Vec<f64>,
}

impl ChannelMessage for PlanarEstimate {
    const TOPIC: &'static str = "/estimate/dekf_planar";
    const SCHEMA_NAME: &'static str = "slidetrack.PlanarEstimate";
    fn json_schema() -> Value {
        derived::<Self>(Self::SCHEMA_NAME)
    }
}

/// The state of the grasp as the online detector sees it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "lowercase")]
pub enum GraspStateName {
    /// No contact yet (or after a drop or release, before a new grasp).
    #[default]
    Idle,
    /// The object is held.
    Holding,
    /// The object is held and slipping.
    Slipping,
    /// The load fell while the gripper stayed closed: the object was lost.
    Dropped,
    /// The load fell because the gripper opened.
    Released,
}

/// `/estimate/slip`: the online grasp-state detector's decision at one
/// tactile scan, with the scores it was decided on (the thresholds are in
/// the channel metadata).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct SlipEstimate {
    /// Holding, slipping or dropped (or idle, released).
    pub state: GraspStateName,
    /// The normal load: the sum of the baseline-subtracted normal (z)
    /// counts of every taxel (counts).
    pub load: f64,
    /// The load over its running peak since the hold began (0 before a
    /// hold); a drop is declared when it falls below the drop ratio.
    pub load_ratio: f64,
    /// The slip score (its unit in the channel metadata `slip_score`);
    /// slipping is declared above the enter threshold.
    pub slip_score: f64,
}

impl ChannelMessage for SlipEstimate {
    const TOPIC: &'static str = "/estimate/slip";
    const SCHEMA_NAME: &'static str = "slidetrack.SlipEstimate";
    fn json_schema() -> Value {
        derived::<Self>(Self::SCHEMA_NAME)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn keys(v: &Value) -> Vec<String> {
        let mut k: Vec<String> = v.as_object().map(|o| o.keys().cloned().collect()).unwrap_or_default();
        k.sort();
        k
    }

    #[test]
    fn messages_serialize_exactly_the_schema_properties() {
        let pose = GroundTruthPose {
            position_in_hand_m: [0.01, 0.02, 0.2],
            orientation_in_hand: Quaternion { x: 0.0, y: 0.0, z: 0.0, w: 1.0 },
            ..GroundTruthPose::default()
        };
        let v = serde_json::to_value(pose).unwrap();
        assert_eq!(keys(&v), keys(&GroundTruthPose::json_schema()["properties"]));
        assert_eq!(serde_json::from_value::<GroundTruthPose>(v).unwrap(), pose);
        let planar = GroundTruthPlanar(PlanarState {
            translation_m: [0.001, -0.002],
            rotation_rad: 0.05,
            ..PlanarState::default()
        });
        let v = serde_json::to_value(planar).unwrap();
        assert_eq!(keys(&v), keys(&GroundTruthPlanar::json_schema()["properties"]));
        assert_eq!(serde_json::from_value::<GroundTruthPlanar>(v).unwrap(), planar);
        let est = PlanarEstimate { state: planar.0, covariance: vec![0.0; 36] };
        let v = serde_json::to_value(&est).unwrap();
        assert_eq!(keys(&v), keys(&PlanarEstimate::json_schema()["properties"]));
        let slip =
            SlipEstimate { state: GraspStateName::Dropped, load: 120.0, load_ratio: 0.05, slip_score: 3.0 };
        let v = serde_json::to_value(slip).unwrap();
        assert_eq!(v["state"], "dropped");
        assert_eq!(keys(&v), keys(&SlipEstimate::json_schema()["properties"]));
        assert_eq!(serde_json::from_value::<SlipEstimate>(v).unwrap(), slip);
    }
}
