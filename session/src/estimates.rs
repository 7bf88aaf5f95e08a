//! The channels of the sliding trackers: the dEKF's input and estimate, and
//! the causal Kalman filter on the marker.

use serde::{Deserialize, Serialize};
use serde_json::Value;

use super::messages::ChannelMessage;
use super::schema::{self, array, number};

/// Channel metadata key of `/tactile/derivative` listing its channels (JSON array).
pub const DERIVATIVE_CHANNELS_KEY: &str = "channels";

/// `/tactile/derivative`: what the dEKF's feature network read at one filter
/// step, in the model's channel order, before normalisation: the derivative
/// of the baseline-subtracted signal (counts/s), or the signal itself
/// (counts) for a model trained on the plain signal.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct TactileDerivative {
    /// One value per model channel (counts/s, or counts for `raw` models).
    pub values: Vec<f64>,
}

impl ChannelMessage for TactileDerivative {
    const TOPIC: &'static str = "/tactile/derivative";
    const SCHEMA_NAME: &'static str = "slidetrack.TactileDerivative";
    fn json_schema() -> Value {
        let values = serde_json::json!({
            "type": "array",
            "description": "one value per model channel, in the order of the channel metadata `channels` (counts/s; counts for raw models)",
            "items": number("channel value"),
        });
        schema::message(
            Self::SCHEMA_NAME,
            "The dEKF's measurement at one filter step",
            vec![("values", values)],
        )
    }
}

/// A state estimate along the sliding axis.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct SlidingEstimate {
    /// Position along the sliding axis, 0 where the tracker started (m).
    pub position: f64,
    /// Velocity along the sliding axis (m/s).
    pub velocity: f64,
    /// Covariance of `(position, velocity)`, row-major:
    /// `[[m^2, m^2/s], [m^2/s, m^2/s^2]]`.
    pub covariance: [[f64; 2]; 2],
}

fn estimate_schema(name: &str, description: &str) -> Value {
    let row = |d: &str| array(d, number("covariance entry"), 2);
    let covariance = array(
        "covariance of (position, velocity), row-major: [[m^2, m^2/s], [m^2/s, m^2/s^2]]",
        row("one row of the covariance"),
        2,
    );
    schema::message(
        name,
        description,
        vec![
            ("position", number("position along the sliding axis (m)")),
            ("velocity", number("velocity along the sliding axis (m/s)")),
            ("covariance", covariance),
        ],
    )
}

/// `/estimate/dekf`: the dEKF's estimate after a filter step.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(transparent)]
pub struct DekfEstimate(pub SlidingEstimate);

impl ChannelMessage for DekfEstimate {
    const TOPIC: &'static str = "/estimate/dekf";
    const SCHEMA_NAME: &'static str = "slidetrack.SlidingEstimate";
    fn json_schema() -> Value {
        estimate_schema(Self::SCHEMA_NAME, "A sliding state estimate (position, velocity and covariance)")
    }
}

/// `/estimate/aruco`: a causal constant-velocity Kalman filter on the marker
/// position, at each camera frame (the online counterpart of the ground truth).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(transparent)]
pub struct ArucoEstimate(pub SlidingEstimate);

impl ChannelMessage for ArucoEstimate {
    const TOPIC: &'static str = "/estimate/aruco";
    const SCHEMA_NAME: &'static str = "slidetrack.SlidingEstimate";
    fn json_schema() -> Value {
        estimate_schema(Self::SCHEMA_NAME, "A sliding state estimate (position, velocity and covariance)")
    }
}
