//! The online detector: settings, states, one scan in, one decision out.

use serde::{Deserialize, Serialize};

use super::error::GraspError;

/// The contact level of the xela-imanlab recordings (counts): the hold
/// begins when the normal load first reaches it.
pub const DEFAULT_CONTACT_LOAD_COUNTS: f64 = 5_000.0;

/// The drop threshold on `load / running peak`: dropped grasps fall below
/// 0.022, kept ones never below 0.28 (see the module docs for the choice).
pub const DEFAULT_DROP_LOAD_RATIO: f64 = 0.1;

/// Growth of the gripper opening over its minimum during the hold (m) that
/// makes a loss of load a deliberate release rather than a drop.
pub const DEFAULT_RELEASE_OPENING_M: f64 = 0.005;

/// Settings of [`GraspDetector`]; every threshold of its rules.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct GraspDetectorConfig {
    /// Normal load at which a hold begins (counts, the caller's load sum).
    /// Sensor-dependent; it must lie well above the load of a light touch,
    /// since a touch that reaches it and goes away reads as a drop.
    pub contact_load_counts: f64,
    /// A held object is lost when `load / running peak` falls below this
    /// (dimensionless, in (0, 1)).
    pub drop_load_ratio: f64,
    /// A loss of load while the gripper opening has grown by more than this
    /// over its minimum during the hold is a release, not a drop (m).
    pub release_opening_m: f64,
    /// The Holding <-> Slipping hysteresis; `None` (the default): the state
    /// never becomes Slipping, the score is only passed through.
    pub slip: Option<SlipHysteresis>,
}

impl Default for GraspDetectorConfig {
    fn default() -> Self {
        GraspDetectorConfig {
            contact_load_counts: DEFAULT_CONTACT_LOAD_COUNTS,
            drop_load_ratio: DEFAULT_DROP_LOAD_RATIO,
            release_opening_m: DEFAULT_RELEASE_OPENING_M,
            slip: None,
        }
    }
}

/// Thresholds on the slip score, in the unit of the caller's score (for a
/// tracker's slip speed m/s, for a shear rate counts/s).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SlipHysteresis {
    /// Holding becomes Slipping when the score is above this (score unit).
    pub enter_score: f64,
    /// Slipping becomes Holding when the score is below this (score unit,
    /// at most `enter_score`).
    pub exit_score: f64,
    /// How long the score must stay above `enter_score` before Slipping (s),
    /// measured between fresh scans; 0 (the default): on the first one.
    #[serde(default)]
    pub enter_min_s: f64,
}

impl GraspDetectorConfig {
    /// Checks every setting; the detector only runs on valid ones.
    pub fn validate(&self) -> Result<(), GraspError> {
        let bad = |field: &'static str, value: f64, reason: &'static str| {
            Err(GraspError::InvalidConfig { field, value, reason })
        };
        if !(self.contact_load_counts.is_finite() && self.contact_load_counts > 0.0) {
            return bad("contact_load_counts", self.contact_load_counts, "must be finite and positive");
        }
        if !(self.drop_load_ratio > 0.0 && self.drop_load_ratio < 1.0) {
            return bad("drop_load_ratio", self.drop_load_ratio, "must lie in (0, 1)");
        }
        if !(self.release_opening_m.is_finite() && self.release_opening_m >= 0.0) {
            return bad("release_opening_m", self.release_opening_m, "must be finite and not negative");
        }
        if let Some(slip) = self.slip {
            if !slip.enter_score.is_finite() {
                return bad("slip.enter_score", slip.enter_score, "must be finite");
            }
            if !(slip.exit_score.is_finite() && slip.exit_score <= slip.enter_score) {
                return bad("slip.exit_score", slip.exit_score, "must be finite and at most enter_score");
            }
            if !(slip.enter_min_s.is_finite() && slip.enter_min_s >= 0.0) {
                return bad("slip.enter_min_s", slip.enter_min_s, "must be finite and not negative");
            }
        }
        Ok(())
    }
}

/// What the hand is doing with the object.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum GraspState {
    /// No contact: before the first grasp, or after a drop or a release once
    /// the load is back under the contact level.
    Idle,
    /// Held: the load reached the contact level and has not collapsed.
    Holding,
    /// Held, with the slip score above the hysteresis (see [`SlipHysteresis`]).
    Slipping,
    /// The load collapsed while the gripper stayed closed: the object fell.
    Dropped,
    /// The load collapsed after the gripper opened: let go on purpose.
    Released,
}

impl GraspState {
    /// Holding or Slipping: the object is in the hand.
    pub fn is_held(self) -> bool {
        matches!(self, GraspState::Holding | GraspState::Slipping)
    }

    /// The name used in logs (`"holding"`, ...), as serde writes it.
    pub fn as_str(self) -> &'static str {
        match self {
            GraspState::Idle => "idle",
            GraspState::Holding => "holding",
            GraspState::Slipping => "slipping",
            GraspState::Dropped => "dropped",
            GraspState::Released => "released",
        }
    }
}

/// One tactile scan as the detector reads it. A non-finite number is a
/// missing value (`load_counts` NaN: no load this scan).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct GraspScan {
    /// Time of the scan (s, any origin, not going back).
    pub t_s: f64,
    /// Normal load: the sum of the baseline-subtracted normal (z) counts of
    /// every taxel in contact with the object (counts).
    pub load_counts: f64,
    /// Slip score, non-negative, in the unit the caller chose for it.
    pub slip_score: Option<f64>,
    /// Gripper opening (m): distance between the fingers, or anything that
    /// grows by the same amount when the gripper opens.
    pub opening_m: Option<f64>,
    /// The hand is commanded to let go (a protocol's release phase): a loss
    /// of load is then a release whatever the opening says.
    #[serde(default)]
    pub releasing: bool,
}

impl GraspScan {
    /// A scan with only the load (counts) at `t_s` (s).
    pub fn load(t_s: f64, load_counts: f64) -> GraspScan {
        GraspScan { t_s, load_counts, slip_score: None, opening_m: None, releasing: false }
    }

    /// The same scan while the hand is commanded to let go.
    pub fn releasing(self) -> GraspScan {
        GraspScan { releasing: true, ..self }
    }

    /// The same scan with a slip score (the caller's unit).
    pub fn with_slip(self, slip_score: f64) -> GraspScan {
        GraspScan { slip_score: Some(slip_score), ..self }
    }

    /// The same scan with the gripper opening (m).
    pub fn with_opening(self, opening_m: f64) -> GraspScan {
        GraspScan { opening_m: Some(opening_m), ..self }
    }
}

/// The decision after one scan and the numbers it was made on, for logs.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct GraspReading {
    /// Time of the scan (s), as given.
    pub t_s: f64,
    /// The state after this scan.
    pub state: GraspState,
    /// The state differs from the previous reading's.
    pub changed: bool,
    /// The scan brought new values; false for a repeat of the previous
    /// scan's values or a scan with a non-finite time (nothing decided).
    pub fresh: bool,
    /// Holds begun so far: 1 during the first grasp, 2 after a re-grasp.
    pub grasp: u32,
    /// This scan's load (counts); `None` when missing.
    pub load_counts: Option<f64>,
    /// Running peak of the load since the current hold began (counts);
    /// `None` in Idle.
    pub peak_load_counts: Option<f64>,
    /// `load_counts / peak_load_counts` (dimensionless); `None` in Idle or
    /// when the load is missing.
    pub load_ratio: Option<f64>,
    /// This scan's slip score (the caller's unit); `None` when missing.
    pub slip_score: Option<f64>,
    /// Growth of the opening over its minimum during the hold (m), from the
    /// latest opening seen; `None` before one is seen in this hold.
    pub opening_growth_m: Option<f64>,
    /// The drop threshold compared with `load_ratio`.
    pub drop_load_ratio: f64,
    /// The enter threshold compared with `slip_score`, if any.
    pub slip_enter_score: Option<f64>,
    /// The exit threshold compared with `slip_score`, if any.
    pub slip_exit_score: Option<f64>,
}

/// The values of a scan, bit for bit, to recognise repeated rows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct ScanBits {
    load: Option<u64>,
    slip: Option<u64>,
    opening: Option<u64>,
    releasing: bool,
}

/// A finite value, or `None`.
fn finite(x: Option<f64>) -> Option<f64> {
    x.filter(|v| v.is_finite())
}

/// The online grasp-state detector: feed every tactile scan to
/// [`GraspDetector::update`]. Holds no heap memory: a call never allocates.
#[derive(Clone, Debug)]
pub struct GraspDetector {
    cfg: GraspDetectorConfig,
    state: GraspState,
    grasp: u32,
    /// Running peak of the load in the current or the last hold (counts);
    /// set afresh when a hold begins.
    peak_load_counts: f64,
    /// Smallest and latest opening seen in this hold (m).
    min_opening_m: Option<f64>,
    last_opening_m: Option<f64>,
    /// Time of the first fresh scan of the current run above `enter_score` (s).
    slip_above_since_s: Option<f64>,
    last_bits: Option<ScanBits>,
    last: GraspReading,
}

impl GraspDetector {
    /// A detector in Idle; fails on invalid settings.
    pub fn new(cfg: GraspDetectorConfig) -> Result<GraspDetector, GraspError> {
        cfg.validate()?;
        let last = GraspReading {
            t_s: f64::NAN,
            state: GraspState::Idle,
            changed: false,
            fresh: false,
            grasp: 0,
            load_counts: None,
            peak_load_counts: None,
            load_ratio: None,
            slip_score: None,
            opening_growth_m: None,
            drop_load_ratio: cfg.drop_load_ratio,
            slip_enter_score: cfg.slip.map(|s| s.enter_score),
            slip_exit_score: cfg.slip.map(|s| s.exit_score),
        };
        Ok(GraspDetector {
            cfg,
            state: GraspState::Idle,
            grasp: 0,
            peak_load_counts: 0.0,
            min_opening_m: None,
            last_opening_m: None,
            slip_above_since_s: None,
            last_bits: None,
            last,
        })
    }

    /// The settings.
    pub fn config(&self) -> &GraspDetectorConfig {
        &self.cfg
    }

    /// The current state.
    pub fn state(&self) -> GraspState {
        self.state
    }

    /// The latest reading (before any scan: Idle, `t_s` NaN).
    pub fn last_reading(&self) -> &GraspReading {
        &self.last
    }

    /// Reads one scan and returns the decision. A scan whose time is not
    /// finite, or whose values equal the previous scan's bit for bit (a
    /// stream repeating rows faster than the sensor refreshes), decides
    /// nothing: the previous reading comes back with this `t_s` and
    /// `fresh == false`. A missing load keeps the load rules (contact, drop,
    /// release) where they are, a missing slip score the slip rule, a missing
    /// opening leaves the latest one in force.
    pub fn update(&mut self, scan: GraspScan) -> GraspReading {
        let load = finite(Some(scan.load_counts));
        let slip = finite(scan.slip_score);
        let opening = finite(scan.opening_m);
        let bits = ScanBits {
            load: load.map(f64::to_bits),
            slip: slip.map(f64::to_bits),
            opening: opening.map(f64::to_bits),
            releasing: scan.releasing,
        };
        if !scan.t_s.is_finite() || self.last_bits == Some(bits) {
            self.last.t_s = scan.t_s;
            self.last.changed = false;
            self.last.fresh = false;
            return self.last;
        }
        self.last_bits = Some(bits);
        let previous = self.state;
        if self.state.is_held() {
            self.see_opening(opening);
        }
        if let Some(load) = load {
            self.step_load(load, opening, scan.releasing);
        }
        if self.state.is_held()
            && let (Some(score), Some(hysteresis)) = (slip, self.cfg.slip)
        {
            self.step_slip(scan.t_s, score, hysteresis);
        }
        self.last = self.reading(scan.t_s, previous, load, slip);
        self.last
    }

    fn see_opening(&mut self, opening: Option<f64>) {
        if let Some(o) = opening {
            self.last_opening_m = Some(o);
            self.min_opening_m = Some(self.min_opening_m.map_or(o, |m| m.min(o)));
        }
    }

    fn opening_growth_m(&self) -> Option<f64> {
        Some(self.last_opening_m? - self.min_opening_m?)
    }

    /// The load rules: contact, drop or release, back to Idle.
    fn step_load(&mut self, load: f64, opening: Option<f64>, releasing: bool) {
        match self.state {
            GraspState::Idle if load >= self.cfg.contact_load_counts => {
                self.state = GraspState::Holding;
                self.grasp += 1;
                self.peak_load_counts = load;
                self.min_opening_m = None;
                self.last_opening_m = None;
                self.slip_above_since_s = None;
                self.see_opening(opening);
            }
            GraspState::Holding | GraspState::Slipping => {
                self.peak_load_counts = self.peak_load_counts.max(load);
                if load / self.peak_load_counts < self.cfg.drop_load_ratio {
                    let opened =
                        releasing || self.opening_growth_m().is_some_and(|g| g > self.cfg.release_opening_m);
                    self.state = if opened { GraspState::Released } else { GraspState::Dropped };
                }
            }
            GraspState::Dropped | GraspState::Released if load < self.cfg.contact_load_counts => {
                self.state = GraspState::Idle;
            }
            _ => {}
        }
    }

    /// The slip hysteresis, on a held object.
    fn step_slip(&mut self, t_s: f64, score: f64, hysteresis: SlipHysteresis) {
        match self.state {
            GraspState::Holding if score > hysteresis.enter_score => {
                let since = *self.slip_above_since_s.get_or_insert(t_s);
                if t_s - since >= hysteresis.enter_min_s {
                    self.state = GraspState::Slipping;
                }
            }
            GraspState::Holding => self.slip_above_since_s = None,
            GraspState::Slipping if score < hysteresis.exit_score => {
                self.state = GraspState::Holding;
                self.slip_above_since_s = None;
            }
            _ => {}
        }
    }

    fn reading(&self, t_s: f64, previous: GraspState, load: Option<f64>, slip: Option<f64>) -> GraspReading {
        let in_hold = self.state != GraspState::Idle;
        let peak = in_hold.then_some(self.peak_load_counts);
        GraspReading {
            t_s,
            state: self.state,
            changed: self.state != previous,
            fresh: true,
            grasp: self.grasp,
            load_counts: load,
            peak_load_counts: peak,
            load_ratio: peak.zip(load).map(|(p, l)| l / p),
            slip_score: slip,
            opening_growth_m: if in_hold { self.opening_growth_m() } else { None },
            ..self.last
        }
    }
}
