//! The metadata records of a session: what was recorded (`slidetrack`) and
//! how it ended (`slidetrack.outcome`).

use std::collections::BTreeMap;

/// Name of the metadata record describing the session, written when recording starts.
pub const SESSION_METADATA: &str = "slidetrack";
/// Name of the metadata record written when recording ends.
pub const OUTCOME_METADATA: &str = "slidetrack.outcome";

/// The `slidetrack` metadata record. MCAP metadata values are strings, so the
/// configurations are stored as TOML text and numbers in decimal.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct SessionMetadata {
    /// Version of the software that recorded the session.
    pub software_version: String,
    /// Rig name (`sim` or the real rig's name).
    pub rig: String,
    /// The rig configuration, as TOML.
    pub rig_config: String,
    /// Object name.
    pub object: String,
    /// The object configuration, as TOML.
    pub object_config: String,
    /// Trial identifier.
    pub trial: String,
    /// Seed of the random streams (simulation noise, protocol jitter).
    pub seed: u64,
    /// Wall-clock start, RFC 3339 (for example `2026-11-21T06:03:07Z`).
    pub started_at: String,
}

impl SessionMetadata {
    /// The record's key/value map.
    pub fn to_map(&self) -> BTreeMap<String, String> {
        [
            ("software_version", self.software_version.clone()),
            ("rig", self.rig.clone()),
            ("rig_config", self.rig_config.clone()),
            ("object", self.object.clone()),
            ("object_config", self.object_config.clone()),
            ("trial", self.trial.clone()),
            ("seed", self.seed.to_string()),
            ("started_at", self.started_at.clone()),
        ]
        .into_iter()
        .map(|(k, v)| (k.to_string(), v))
        .collect()
    }

    /// From a record's map; missing keys are empty and an unparsable seed is `None`.
    pub fn from_map(map: &BTreeMap<String, String>) -> Option<SessionMetadata> {
        let get = |k: &str| map.get(k).cloned().unwrap_or_default();
        Some(SessionMetadata {
            software_version: get("software_version"),
            rig: get("rig"),
            rig_config: get("rig_config"),
            object: get("object"),
            object_config: get("object_config"),
            trial: get("trial"),
            seed: map.get("seed").map_or(Some(0), |s| s.parse().ok())?,
            started_at: get("started_at"),
        })
    }
}

/// The `slidetrack.outcome` metadata record.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct SessionOutcome {
    /// True when the trial ran to its end.
    pub completed: bool,
    /// Why the trial stopped early, if it did.
    pub abort_reason: Option<String>,
    /// Images the recorder dropped because its queue was full.
    pub images_dropped: u64,
}

impl SessionOutcome {
    /// The record's key/value map (`abort_reason` is empty when there is none).
    pub fn to_map(&self) -> BTreeMap<String, String> {
        BTreeMap::from([
            ("completed".to_string(), self.completed.to_string()),
            ("abort_reason".to_string(), self.abort_reason.clone().unwrap_or_default()),
            ("images_dropped".to_string(), self.images_dropped.to_string()),
        ])
    }

    /// From a record's map, `None` when a value does not parse.
    pub fn from_map(map: &BTreeMap<String, String>) -> Option<SessionOutcome> {
        let reason = map.get("abort_reason").filter(|s| !s.is_empty()).cloned();
        Some(SessionOutcome {
            completed: map.get("completed")?.parse().ok()?,
            abort_reason: reason,
            images_dropped: map.get("images_dropped")?.parse().ok()?,
        })
    }
}
