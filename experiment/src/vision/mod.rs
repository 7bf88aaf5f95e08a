//! Vision tracking runs, assembled from their options: the inputs a tracker
//! reads (a session, a YCB-Video-style directory, the `[rgbd]` camera of a
//! rig), its measurement sources, the tracker itself, and what the commands
//! `vision simulate|track|eval` and `track --vision` on a camera report.

pub mod camera;
pub mod camera_vision;
pub mod eval;
pub mod input;
pub mod live;
pub mod offline;
pub mod shared_camera;
pub mod simulate;

pub use slidetrack_estimators::metrics::SequenceMetrics;
pub use slidetrack_vision::sources::ExternalConfig;
pub use slidetrack_vision::{PoseReset, TrackerKind};

/// Where a tracker's masks and poses come from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Measurements {
    /// The input's own: a session's `/vision/mask` and `/vision/pose`, or the
    /// label masks of a YCB-Video directory (every frame, no delay).
    Input,
    /// The imitated slow network (5 fps, 200 ms late) from the input's truth.
    Network,
    /// The input's ground truth, every frame, without delay.
    Truth,
    /// Poses from an ArUco marker fixed to the object, masks rendered from
    /// the model at them.
    Aruco,
    /// Masks and poses from another process over a local socket.
    External,
}

/// How a tracker starts.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TrackerStart {
    /// From the first pose measurement that arrives.
    Measurement,
    /// From the input's true pose of the first frame.
    Truth,
    /// From the true pose of the first frame moved 5 cm along each axis and
    /// turned 10 degrees on each Euler angle (thesis Sec. 4.2.3).
    Perturbed,
}

/// Session metadata keys and values: what produced a session.
pub type Metadata = std::collections::BTreeMap<String, String>;
