//! Why a trial stops early, and the limits that decide it.

use serde::{Deserialize, Serialize};
use slidetrack_core::{DeviceError, Finger};

/// Limits checked throughout a trial. Crossing one aborts it with a safe release.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SafetyConfig {
    /// A raw channel within this many counts of 0 or 65535 is saturated.
    pub saturation_margin_counts: u16,
    /// Consecutive saturated scans that abort (a single spike does not).
    pub saturation_scans: u32,
    /// Largest age of the newest tactile scan when the controller acts (s).
    pub max_data_age_s: f64,
}

impl Default for SafetyConfig {
    fn default() -> Self {
        SafetyConfig { saturation_margin_counts: 0, saturation_scans: 3, max_data_age_s: 0.050 }
    }
}

/// Why a trial ended before its end.
#[derive(Clone, Debug, PartialEq)]
pub enum AbortReason {
    /// The marker shows the object beyond the travel limit.
    TravelLimit {
        /// Travel seen (m).
        travel_m: f64,
        /// The limit (m).
        limit_m: f64,
    },
    /// A tactile channel stayed at the end of its range.
    Saturated {
        /// The finger.
        finger: Finger,
        /// The channel, `x`, `y` or `z`.
        axis: &'static str,
        /// Its value (counts).
        counts: u16,
        /// For how many consecutive scans.
        scans: u32,
    },
    /// The newest tactile scan was too old when the controller needed it.
    StaleData {
        /// Age of the scan (s).
        age_s: f64,
        /// The limit (s).
        limit_s: f64,
    },
    /// A device failed.
    Device(DeviceError),
    /// No finger touched the object before the closing timeout.
    NoContact {
        /// The fingers that did not reach contact.
        fingers: Vec<Finger>,
        /// The timeout (s).
        timeout_s: f64,
    },
    /// Every finger lost contact with the object (it fell).
    ContactLost,
    /// The recorder or another consumer of the data failed.
    Recording(String),
    /// The user asked to stop.
    Interrupted,
}

impl std::fmt::Display for AbortReason {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            AbortReason::TravelLimit { travel_m, limit_m } => write!(
                f,
                "the object travelled {:.1} cm along the sliding axis, beyond the limit of {:.1} cm",
                travel_m * 100.0,
                limit_m * 100.0
            ),
            AbortReason::Saturated { finger, axis, counts, scans } => write!(
                f,
                "tactile channel {}.{axis} saturated ({counts} counts for {scans} scans)",
                finger.name()
            ),
            AbortReason::StaleData { age_s, limit_s } => write!(
                f,
                "tactile data was {:.0} ms old when the controller needed it (limit {:.0} ms)",
                age_s * 1e3,
                limit_s * 1e3
            ),
            AbortReason::Device(e) => write!(f, "device error: {e}"),
            AbortReason::NoContact { fingers, timeout_s } => {
                let names: Vec<_> = fingers.iter().map(|f| f.name()).collect();
                write!(f, "no contact within {timeout_s} s for: {}", names.join(", "))
            }
            AbortReason::ContactLost => write!(f, "every finger lost contact with the object"),
            AbortReason::Recording(e) => write!(f, "recording failed: {e}"),
            AbortReason::Interrupted => write!(f, "interrupted by the user"),
        }
    }
}
