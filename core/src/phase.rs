//! The phases of the controlled-sliding protocol (thesis Sec. 6.2.3), as
//! the controller runs them and as sessions record them.

use serde::{Deserialize, Serialize};

/// The phase of a trial.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Phase {
    /// Averaging the open-hand tactile baseline.
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
