//! The grasp-state stage: the online grasp detector
//! ([`slidetrack_estimators::slip`]) on every baseline-subtracted tactile
//! scan, as `slidetrack track` runs it live, `slidetrack replay` on a
//! recording and `slidetrack slip` offline. One scan in, one
//! `/estimate/slip` message out.
//!
//! Per scan (`[taxel][x, y, z]` counts, every taxel of every sensor):
//!
//! - **load** `L = sum_i z_i` (counts): the normal load the drop rule reads;
//! - **slip score** `S = sqrt(mean_i(dx_i^2 + dy_i^2))` (counts/s): the shear
//!   rate, `dx_i`, `dy_i` the per-channel constant-velocity derivative filter
//!   ([`DerivativeFilter`], the dEKF's) on each taxel's x and y counts;
//! - **opening**: the gripper's opening (m), the latest one the hand
//!   reported (`/hand/state` `opening`) before the scan, when it reports one.
//!
//! The derivative filter runs without its outlier gate
//! ([`shear_rate_filter`]): at a 10 Hz refresh a real shear change between
//! two refreshes lies many standard deviations from the prediction, and the
//! gate would leave it out and then restart the channel with a derivative of
//! 0, hiding exactly the fast changes the score is for.
//!
//! A scan equal to the previous one bit for bit (a stream that repeats rows
//! faster than the sensor refreshes, as xela-imanlab's ~10 Hz values recorded
//! at ~40 Hz) does not step the filter, and the detector, seeing the same
//! load and score, decides nothing on it: the states at the refreshes are
//! those of the deduplicated stream.

use std::collections::BTreeMap;

use slidetrack_core::{TactileInfo, TimeNs};
use slidetrack_estimators::derivative::{DerivativeFilter, DerivativeFilterConfig};
use slidetrack_estimators::slip::{
    DEFAULT_CONTACT_LOAD_COUNTS, GraspDetector, GraspDetectorConfig, GraspError, GraspReading, GraspScan,
    GraspState,
};
use slidetrack_session::{GraspStateName, SlipEstimate};

/// Unit of the slip score.
pub const SLIP_SCORE_UNIT: &str = "counts/s";

/// The slip score in words (channel metadata `slip_score`).
pub const SLIP_SCORE_DEFINITION: &str = "shear rate (counts/s): sqrt(mean over every taxel of every sensor of \
     dx^2 + dy^2), dx and dy the constant-velocity derivative filter's estimates of the taxel's \
     baseline-subtracted x and y counts per second (filter settings in `derivative_filter`)";

/// The load in words (channel metadata `load`).
pub const LOAD_DEFINITION: &str =
    "normal load (counts): the sum of the baseline-subtracted z counts of every taxel of every sensor";

/// The gripper opening in words (channel metadata `opening`).
pub const OPENING_DEFINITION: &str = "the latest /hand/state `opening` (m) reported before the scan, when the \
     hand reports one; without it every fall of the load is a drop, never a release";

/// The derivative filter of the slip score: the dEKF's settings without the
/// outlier gate (see the module docs).
pub fn shear_rate_filter() -> DerivativeFilterConfig {
    DerivativeFilterConfig { outlier_gate_sigma: 0.0, ..DerivativeFilterConfig::default() }
}

/// The detector's state as `/estimate/slip` names it.
pub fn state_name(state: GraspState) -> GraspStateName {
    match state {
        GraspState::Idle => GraspStateName::Idle,
        GraspState::Holding => GraspStateName::Holding,
        GraspState::Slipping => GraspStateName::Slipping,
        GraspState::Dropped => GraspStateName::Dropped,
        GraspState::Released => GraspStateName::Released,
    }
}

/// The normal load of a scan (counts): the sum of every taxel's z.
pub fn normal_load_counts(zeroed: &[[f64; 3]]) -> f64 {
    zeroed.iter().map(|v| v[2]).sum()
}

/// The shear rate (counts/s) from the derivatives of every taxel's x and y
/// (`[dx_0, dy_0, dx_1, dy_1, ...]`, counts/s): the RMS over the taxels of
/// `sqrt(dx^2 + dy^2)`; 0 without taxels.
pub fn shear_rate_rms(xy_rates: &[f64]) -> f64 {
    let taxels = xy_rates.len() / 2;
    if taxels == 0 {
        return 0.0;
    }
    (xy_rates.iter().map(|d| d * d).sum::<f64>() / taxels as f64).sqrt()
}

/// True when `a` and `b` hold the same numbers bit for bit.
fn same_bits(a: &[[f64; 3]], b: &[[f64; 3]]) -> bool {
    a.len() == b.len() && a.iter().flatten().zip(b.iter().flatten()).all(|(x, y)| x.to_bits() == y.to_bits())
}

/// A finite number, or 0 (JSON has no NaN).
fn finite_or_zero(x: Option<f64>) -> f64 {
    x.filter(|v| v.is_finite()).unwrap_or(0.0)
}

/// The grasp detector on a stream of baseline-subtracted scans (see the
/// module docs). Allocates only when created.
#[derive(Clone, Debug)]
pub struct SlipStage {
    detector: GraspDetector,
    derivative: DerivativeFilter,
    /// x and y of every taxel of the scan being read (counts).
    xy: Vec<f64>,
    /// The previous scan, to recognise repeated rows.
    previous: Vec<[f64; 3]>,
    score: f64,
    opening_m: Option<f64>,
    /// The hand is commanded to let go.
    releasing: bool,
}

impl SlipStage {
    /// The stage on scans of `tactile` with the detector settings `cfg`;
    /// fails on invalid settings.
    /// The contact level is the simulated rig's ([`for_source`]) on a
    /// simulated source when `cfg` has the default one.
    pub fn new(cfg: GraspDetectorConfig, tactile: &TactileInfo) -> Result<SlipStage, GraspError> {
        let taxels = tactile.layout.taxel_count();
        Ok(SlipStage {
            detector: GraspDetector::new(for_source(cfg, tactile))?,
            derivative: DerivativeFilter::new(shear_rate_filter(), 2 * taxels),
            xy: vec![f64::NAN; 2 * taxels],
            previous: Vec::with_capacity(taxels),
            score: 0.0,
            opening_m: None,
            releasing: false,
        })
    }

    /// The detector's settings.
    pub fn config(&self) -> &GraspDetectorConfig {
        self.detector.config()
    }

    /// The hand is now commanded to let go (the protocol's release, an
    /// abort, the end): a loss of load from here on is a release.
    pub fn set_releasing(&mut self) {
        self.releasing = true;
    }

    /// Whether a protocol event says the hand is letting go.
    pub fn protocol_event(&mut self, event: &slidetrack_core::Phase) {
        if matches!(
            event,
            slidetrack_core::Phase::Release | slidetrack_core::Phase::Aborted | slidetrack_core::Phase::Done
        ) {
            self.set_releasing();
        }
    }

    /// The gripper opening the hand reported (m); `None` keeps the latest.
    pub fn set_opening(&mut self, opening_m: Option<f64>) {
        if let Some(o) = opening_m.filter(|o| o.is_finite()) {
            self.opening_m = Some(o);
        }
    }

    /// The detector's latest reading (its thresholds, peak, opening growth).
    pub fn reading(&self) -> &GraspReading {
        self.detector.last_reading()
    }

    /// One scan at `t`: the baseline-subtracted values of every taxel
    /// (counts, layout order; a missing taxel is a missing sample of its
    /// channels). Returns the `/estimate/slip` message of this scan.
    pub fn on_scan(&mut self, t: TimeNs, zeroed: &[[f64; 3]]) -> SlipEstimate {
        let t_s = t.as_secs_f64();
        if !same_bits(zeroed, &self.previous) {
            for (k, xy) in self.xy.chunks_exact_mut(2).enumerate() {
                let v = zeroed.get(k).map_or([f64::NAN; 3], |v| *v);
                xy.copy_from_slice(&v[..2]);
            }
            self.score = shear_rate_rms(self.derivative.step(t_s, &self.xy));
            self.previous.clear();
            self.previous.extend_from_slice(zeroed);
        }
        let mut scan = GraspScan::load(t_s, normal_load_counts(zeroed)).with_slip(self.score);
        scan.opening_m = self.opening_m;
        scan.releasing = self.releasing;
        let r = self.detector.update(scan);
        SlipEstimate {
            state: state_name(r.state),
            load: finite_or_zero(r.load_counts),
            load_ratio: finite_or_zero(r.load_ratio),
            slip_score: finite_or_zero(r.slip_score),
        }
    }

    /// The channel metadata of `/estimate/slip` (see [`channel_metadata`]).
    pub fn metadata(&self) -> serde_json::Result<BTreeMap<String, String>> {
        channel_metadata(self.config())
    }
}

/// The normal load at which the simulated rig's hold begins (counts): its
/// modules' summed z peaks at about 3,800 counts in a grasp (box, default
/// rig), under the XELA patches' contact level.
pub const SIM_CONTACT_LOAD_COUNTS: f64 = 1_000.0;

/// `cfg` for scans of `tactile`: on the simulated rig (device `sim`), the
/// default contact level becomes [`SIM_CONTACT_LOAD_COUNTS`]; a level set
/// by the caller stays.
pub fn for_source(mut cfg: GraspDetectorConfig, tactile: &TactileInfo) -> GraspDetectorConfig {
    if tactile.device == "sim" && cfg.contact_load_counts == DEFAULT_CONTACT_LOAD_COUNTS {
        cfg.contact_load_counts = SIM_CONTACT_LOAD_COUNTS;
    }
    cfg
}

/// The channel metadata of `/estimate/slip` written by a stage with the
/// detector settings `cfg`: `detector` (the settings, JSON), `slip_score`
/// (its definition), `slip_score_unit`, `derivative_filter` (JSON), `load`,
/// `opening`, `repeated_scans`.
pub fn channel_metadata(cfg: &GraspDetectorConfig) -> serde_json::Result<BTreeMap<String, String>> {
    let entries = [
        ("detector", serde_json::to_string(cfg)?),
        ("slip_score", SLIP_SCORE_DEFINITION.to_string()),
        ("slip_score_unit", SLIP_SCORE_UNIT.to_string()),
        ("derivative_filter", serde_json::to_string(&shear_rate_filter())?),
        ("load", LOAD_DEFINITION.to_string()),
        ("opening", OPENING_DEFINITION.to_string()),
        (
            "repeated_scans",
            "a scan equal to the previous one bit for bit keeps the score and decides nothing".to_string(),
        ),
    ];
    Ok(entries.into_iter().map(|(k, v)| (k.to_string(), v)).collect())
}

#[cfg(test)]
mod tests;
