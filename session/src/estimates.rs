//! The channels of the sliding trackers: the dEKF's input and estimate, and
//! the causal Kalman filter on the marker.

use serde::{Deserialize, Serialize};
use serde_json::Value;

use super::channel::ChannelMessage;
use super::schema::derived;

/// Channel metadata key of `/tactile/derivative` listing its channels (JSON array).
pub const DERIVATIVE_CHANNELS_KEY: &str = "channels";

/// `/tactile/derivative`: what the dEKF's feature network read at one filter
/// step, in the model's channel order, before normalisation: the derivative
/// of the baseline-subtracted signal (counts/s), or the signal itself
/// (counts) for a model trained on the plain signal.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct TactileDerivative {
    /// One value per model channel, in the order of the channel metadata
    /// `channels` (counts/s, or counts for `raw` models).
    pub values: Vec<f64>,
}

impl ChannelMessage for TactileDerivative {
    const TOPIC: &'static str = "/tactile/derivative";
    const SCHEMA_NAME: &'static str = "slidetrack.TactileDerivative";
    fn json_schema() -> Value {
        derived::<Self>(Self::SCHEMA_NAME)
    }
}

/// A state estimate along the sliding axis.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct SlidingEstimate {
    /// Position along the sliding axis, 0 where the tracker started (m).
    pub position: f64,
    /// Velocity along the sliding axis (m/s).
    pub velocity: f64,
    /// Covariance of `(position, velocity)`, row-major:
    /// `[[m^2, m^2/s], [m^2/s, m^2/s^2]]`.
    pub covariance: [[f64; 2]; 2],
}

/// `/estimate/dekf`: the dEKF's estimate after a filter step.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(transparent)]
pub struct DekfEstimate(pub SlidingEstimate);

impl ChannelMessage for DekfEstimate {
    const TOPIC: &'static str = "/estimate/dekf";
    const SCHEMA_NAME: &'static str = "slidetrack.SlidingEstimate";
    fn json_schema() -> Value {
        derived::<Self>(Self::SCHEMA_NAME)
    }
}

/// `/estimate/aruco`: a causal constant-velocity Kalman filter on the marker
/// position, at each camera frame (the online counterpart of the ground truth).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(transparent)]
pub struct ArucoEstimate(pub SlidingEstimate);

impl ChannelMessage for ArucoEstimate {
    const TOPIC: &'static str = "/estimate/aruco";
    const SCHEMA_NAME: &'static str = "slidetrack.SlidingEstimate";
    fn json_schema() -> Value {
        derived::<Self>(Self::SCHEMA_NAME)
    }
}
