//! The marker positions along the sliding axis, the measurements of the
//! ground truth, and where they come from.

use nalgebra::Vector3;
use slidetrack_core::TimeNs;

/// Where the marker positions along the sliding axis come from.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum AxisSource {
    /// `position_on_axis_m` as recorded online (the rig's axis and camera
    /// placement at recording time).
    #[default]
    Recorded,
    /// Recomputed from `position_in_camera_m` with the camera placement and
    /// the sliding axis of the rig configuration stored in the session.
    Config,
    /// Recomputed from `position_in_camera_m` along the principal direction
    /// of the marker track.
    Estimate,
}

/// Marker positions along the sliding axis.
#[derive(Clone, Debug, PartialEq)]
pub struct Measurements {
    /// `(camera frame time, position (m))`, first one at 0, times increasing.
    pub positions: Vec<(TimeNs, f64)>,
    /// Camera frames without a usable position.
    pub missing: usize,
    /// Camera frames in all.
    pub frames: usize,
    /// The sliding direction in the camera frame, when it was computed here.
    pub axis_in_camera: Option<Vector3<f64>>,
    /// How the positions were obtained, for the parameters record.
    pub source: String,
}
