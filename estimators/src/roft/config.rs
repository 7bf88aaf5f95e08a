//! What ROFT is given: its parameters ([`RoftConfig`]) and the renderer of
//! the object's depth ([`DepthRenderer`]).

use nalgebra::Isometry3;

use super::velocity::VelocityConfig;
use crate::ukf::UtParams;

/// Renders the depth of the object model, for the outlier test (5.19).
///
/// # Contract
/// `render` writes, for each of `pixels`, the depth (m) of the object placed
/// at `camera_from_object` as seen through that pixel, or `0` where the
/// object is not seen. It must not block on I/O.
pub trait DepthRenderer: Send {
    /// Fills `depth_m` (cleared first) with one value per pixel.
    fn render(&mut self, camera_from_object: &Isometry3<f64>, pixels: &[(u32, u32)], depth_m: &mut Vec<f32>);
}

/// Parameters of ROFT: Table 5.1 and the switches of the ablations (Table 5.6).
#[derive(Clone, Debug, PartialEq)]
pub struct RoftConfig {
    /// `P_0` diagonal for `p` (m²), `v^m` ((m/s)²), `q` (rad²), `ω` ((rad/s)²).
    pub p0: [f64; 4],
    /// Power spectral density `Q_p` of the linear acceleration, (m/s)²/s.
    pub q_p: [f64; 3],
    /// `Q_ω` per step, (rad/s)².
    pub q_omega: [f64; 3],
    /// Measurement variances `R_p` (m²), `R_q` (rad²), `R_v` ((m/s)²), `R_ω` ((rad/s)²).
    pub r: [f64; 4],
    /// `γ` of the outlier test (5.20).
    pub gamma: f64,
    /// The velocity tracker (Table 5.1, lower half).
    pub velocity: VelocityConfig,
    /// Use the velocities in the pose UKF (off: "w/o velocity").
    pub use_velocity: bool,
    /// Use the pose measurements after the first (off: "w/o pose").
    pub use_pose: bool,
    /// Fuse delayed poses at their own frame and replay (off: "w/o pose sync.").
    pub pose_sync: bool,
    /// Reject poses with the depth-rendering test (off: "w/o outlier rej.").
    pub outlier_rejection: bool,
    /// Propagate masks with the flow (off: "w/o segm. sync.").
    pub mask_sync: bool,
    /// Frames of history kept for the synchronisation (flows, velocities,
    /// beliefs); delayed measurements older than this are dropped.
    pub history_frames: usize,
    /// At most this many mask pixels enter the depth comparison (5.19).
    pub max_outlier_pixels: usize,
    /// Unscented transform parameters.
    pub ut: UtParams,
}

impl Default for RoftConfig {
    fn default() -> RoftConfig {
        RoftConfig {
            p0: [1e-3; 4],
            q_p: [1.0; 3],
            q_omega: [1.0; 3],
            r: [1e-3, 1e-4, 1e-1, 1e-4],
            gamma: 2.0,
            velocity: VelocityConfig::default(),
            use_velocity: true,
            use_pose: true,
            pose_sync: true,
            outlier_rejection: true,
            mask_sync: true,
            history_frames: 30,
            max_outlier_pixels: 2000,
            ut: UtParams::default(),
        }
    }
}
