//! The ground-truth channels that `slidetrack label` adds to a session: the
//! smoothed sliding state at every tactile scan, and the marker positions it
//! was computed from. Their parameters ride in the channel metadata
//! ([`GroundTruthParameters`]) so that the result can be reproduced.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};
use serde_json::Value;

use super::channel::ChannelMessage;
use super::schema::derived;

/// Channel metadata key of both ground-truth channels holding the
/// [`GroundTruthParameters`] as JSON.
pub const GROUND_TRUTH_PARAMETERS_KEY: &str = "parameters";

/// Topic prefix of the channels written by the labelling; relabelling
/// replaces every channel under it.
pub const GROUND_TRUTH_PREFIX: &str = "/ground_truth/";

/// `/ground_truth/sliding`: the RTS-smoothed state `(p, v)` of the object
/// along the sliding axis (thesis eq. 6.15), at the log time of a tactile scan.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct GroundTruthSliding {
    /// Position along the sliding axis, 0 at the first valid marker sample (m).
    pub position: f64,
    /// Velocity along the sliding axis (m/s).
    pub velocity: f64,
    /// Covariance of `(position, velocity)`, row-major:
    /// `[[m^2, m^2/s], [m^2/s, m^2/s^2]]`.
    pub covariance: [[f64; 2]; 2],
}

impl ChannelMessage for GroundTruthSliding {
    const TOPIC: &'static str = "/ground_truth/sliding";
    const SCHEMA_NAME: &'static str = "slidetrack.GroundTruthSliding";
    fn json_schema() -> Value {
        derived::<Self>(Self::SCHEMA_NAME)
    }
}

/// `/ground_truth/measurements`: one marker position fed to the filter, at
/// the log time of its camera frame.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct GroundTruthMeasurement {
    /// Marker position along the sliding axis, 0 at the first valid sample (m).
    pub position: f64,
    /// The innovation gate rejected it as an outlier (not used by the filter).
    pub rejected: bool,
    /// Squared Mahalanobis distance of its innovation against the filter's
    /// prediction (dimensionless; in squared standard deviations).
    pub mahalanobis2: f64,
}

impl ChannelMessage for GroundTruthMeasurement {
    const TOPIC: &'static str = "/ground_truth/measurements";
    const SCHEMA_NAME: &'static str = "slidetrack.GroundTruthMeasurement";
    fn json_schema() -> Value {
        derived::<Self>(Self::SCHEMA_NAME)
    }
}

/// Everything needed to recompute the ground truth with another
/// implementation of the same equations, stored as JSON in the metadata of
/// both channels under [`GROUND_TRUTH_PARAMETERS_KEY`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct GroundTruthParameters {
    /// The equations, in words.
    pub model: String,
    /// Units of every quantity.
    pub units: String,
    /// How the sample times are chosen and `dt` computed.
    pub sample_times: String,
    /// How `Q` of a step depends on its `dt`.
    pub process_noise: String,
    /// Spectral density of the position random walk `q_p` (m^2/s).
    pub q_position_m2_per_s: f64,
    /// Spectral density of the velocity random walk `q_v` (m^2/s^3).
    pub q_velocity_m2_per_s3: f64,
    /// Measurement noise variance `R` (m^2).
    pub r_m2: f64,
    /// Initial state `(p (m), v (m/s))` at the first sample.
    pub x0: [f64; 2],
    /// Initial covariance, row-major `[[m^2, m^2/s], [m^2/s, m^2/s^2]]`.
    pub p0: [[f64; 2]; 2],
    /// Innovation gate: largest accepted squared Mahalanobis distance, or
    /// `null` without gating.
    pub gate_max_mahalanobis2: Option<f64>,
    /// The gate accepts the next position after this many rejected in a
    /// row; `null` (and absent, in sessions labelled before it existed):
    /// never.
    #[serde(default)]
    pub gate_reacquire_after: Option<u32>,
    /// Where the measured positions come from.
    pub measurement_source: String,
    /// Direction of positive sliding in the camera frame (unit vector), as used.
    pub axis_in_camera: Option<[f64; 3]>,
    /// How the noise parameters were estimated from the marker positions
    /// (`label --tune`), or `null` when they were given.
    #[serde(default)]
    pub tuning: Option<String>,
    /// The software that labelled the session.
    pub software_version: String,
}

impl GroundTruthParameters {
    /// The channel metadata map holding these parameters.
    pub fn channel_metadata(&self) -> BTreeMap<String, String> {
        // Plain strings and finite numbers always serialize.
        let json = serde_json::to_string(self).unwrap_or_default();
        BTreeMap::from([(GROUND_TRUTH_PARAMETERS_KEY.to_string(), json)])
    }

    /// The parameters stored in channel metadata: `None` without the key,
    /// an error when its JSON does not decode.
    pub fn from_channel_metadata(
        metadata: &BTreeMap<String, String>,
    ) -> Option<Result<GroundTruthParameters, serde_json::Error>> {
        metadata.get(GROUND_TRUTH_PARAMETERS_KEY).map(|s| serde_json::from_str(s))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn keys(v: &Value) -> Vec<String> {
        let mut k: Vec<String> = v.as_object().unwrap().keys().cloned().collect();
        k.sort();
        k
    }

    #[test]
    fn messages_serialize_exactly_the_schema_properties() {
        let gt =
            GroundTruthSliding { position: 0.01, velocity: -0.002, covariance: [[1e-8, 0.0], [0.0, 1e-6]] };
        let value = serde_json::to_value(gt).unwrap();
        assert_eq!(keys(&value), keys(&GroundTruthSliding::json_schema()["properties"]));
        assert_eq!(value["covariance"][1][1], 1e-6);
        let m = GroundTruthMeasurement { position: 0.003, rejected: true, mahalanobis2: 40.0 };
        let value = serde_json::to_value(m).unwrap();
        assert_eq!(keys(&value), keys(&GroundTruthMeasurement::json_schema()["properties"]));
        assert_eq!(serde_json::from_value::<GroundTruthMeasurement>(value).unwrap(), m);
    }

    #[test]
    fn parameters_round_trip_through_channel_metadata() {
        let p = GroundTruthParameters {
            model: "cv".into(),
            units: "SI".into(),
            sample_times: "scans".into(),
            process_noise: "Q dt".into(),
            q_position_m2_per_s: 1e-9,
            q_velocity_m2_per_s3: 1e-5,
            r_m2: 1e-8,
            x0: [0.0, 0.0],
            p0: [[1e-8, 0.0], [0.0, 1e-4]],
            gate_max_mahalanobis2: None,
            gate_reacquire_after: None,
            measurement_source: "position_on_axis_m".into(),
            axis_in_camera: Some([0.0, 0.5, 0.5]),
            tuning: None,
            software_version: "0".into(),
        };
        let back = GroundTruthParameters::from_channel_metadata(&p.channel_metadata()).unwrap().unwrap();
        assert_eq!(back, p);
        assert!(GroundTruthParameters::from_channel_metadata(&BTreeMap::new()).is_none());
    }
}
