//! The phases of the controlled-sliding protocol (thesis Sec. 6.2.3), as
//! the controller runs them and as sessions record them.

use serde::{Deserialize, Serialize};

/// The phase of a trial.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Phase {
    /// Averaging the open-hand tactile baseline.
    #[default]
    Zero,
    /// Closing the fingers until each touches the object.
    Close,
    /// Raising the grasp strength to its maximum.
    Ramp,
    /// Holding the maximum while the object is lifted and settles.
    Settle,
    /// The periodic grasp-strength reference: the object slides and sticks.
    Cycles,
    /// Opening the hand at the end.
    Release,
    /// Finished normally.
    Done,
    /// Stopped by a safety limit or an error.
    Aborted,
}

impl Phase {
    /// Every phase, in the order a complete trial runs them (`Aborted` last).
    pub const ALL: [Phase; 8] = [
        Phase::Zero,
        Phase::Close,
        Phase::Ramp,
        Phase::Settle,
        Phase::Cycles,
        Phase::Release,
        Phase::Done,
        Phase::Aborted,
    ];

    /// Lower-case name, as recorded.
    pub fn name(self) -> &'static str {
        match self {
            Phase::Zero => "zero",
            Phase::Close => "close",
            Phase::Ramp => "ramp",
            Phase::Settle => "settle",
            Phase::Cycles => "cycles",
            Phase::Release => "release",
            Phase::Done => "done",
            Phase::Aborted => "aborted",
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sessions_record_the_lower_case_names() {
        for phase in Phase::ALL {
            let json = serde_json::to_string(&phase).unwrap();
            assert_eq!(json, format!("\"{}\"", phase.name()));
            assert_eq!(serde_json::from_str::<Phase>(&json).unwrap(), phase);
        }
        assert!(serde_json::from_str::<Phase>("\"slide\"").is_err());
    }
}
