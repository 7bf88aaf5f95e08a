//! The simulator's truth about the object, and the trait of its sources
//! (the simulated rig, or a replayed `/sim/truth` channel).

use crate::TimeNs;

/// Speed above which the object counts as sliding (m/s).
pub const SLIDING_SPEED_MPS: f64 = 1e-4;

/// The simulator's own truth at one instant.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SimTruth {
    /// Session time.
    pub t: TimeNs,
    /// Object travel along the sliding axis since the start (m).
    pub position_m: f64,
    /// Object velocity along the sliding axis (m/s).
    pub velocity_mps: f64,
    /// True while the object rests on its support, before the grasp lifts it.
    pub supported: bool,
    /// True once the object has left the fingers.
    pub dropped: bool,
    /// Normal force per finger (N), `[thumb, index, middle]`.
    pub normal_n: [f64; 3],
    /// Friction force per finger along the sliding axis (N), opposing the slide.
    pub friction_n: [f64; 3],
}

impl SimTruth {
    /// True when the object moves faster than [`SLIDING_SPEED_MPS`].
    pub fn sliding(&self) -> bool {
        self.velocity_mps.abs() > SLIDING_SPEED_MPS
    }
}

/// A source of the simulator's own truth (absent on the real rig).
pub trait TruthSource: Send {
    /// The truth at the time of the newest tactile scan.
    fn latest(&mut self) -> Option<SimTruth>;
}
