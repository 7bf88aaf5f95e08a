//! `/estimate/odometry/<tracker>`: a vision tracker's estimate with its
//! covariance, as ROS's `nav_msgs/Odometry` carries one: the pose of the
//! object in the camera frame, its twist in the object's own frame, and a
//! 6 x 6 covariance for each.
//!
//! The pose, transform and velocity channels of the trackers
//! (`vision_pose`) carry the same estimate without covariance, in the
//! schemas Foxglove draws; this channel adds what a consumer of the
//! uncertainty needs (`export --ros2-bag` and `--ros2` publish it as
//! `nav_msgs/msg/Odometry`).

use serde::{Deserialize, Serialize};
use serde_json::Value;

use super::channel::{ChannelMessage, channel};
use super::schema::derived;
use super::vision::Quaternion;

/// A pose and twist with covariances (`slidetrack.Odometry`).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct Odometry {
    /// The frame of the pose (`camera`).
    pub frame_id: String,
    /// The object's frame (`object/<tracker>`), which the twist is in.
    pub child_frame_id: String,
    /// The object's origin in `frame_id` (m).
    pub position_m: [f64; 3],
    /// `camera_from_object` rotation.
    pub orientation: Quaternion,
    /// Covariance of `(x, y, z, rotation about frame_id's X, Y, Z axes)`
    /// (m², m·rad, rad²), row-major, 36 values. The rotation is the
    /// rotation vector of the error on the left (`R = exp(δθ) R̂`).
    pub pose_covariance: Vec<f64>,
    /// Velocity of the object's origin, in the object frame (m/s).
    pub linear_velocity_in_child_mps: [f64; 3],
    /// Angular velocity, in the object frame (rad/s).
    pub angular_velocity_in_child_radps: [f64; 3],
    /// Covariance of `(linear, angular)` velocity in the object frame
    /// ((m/s)², m/s·rad/s, (rad/s)²), row-major, 36 values.
    pub twist_covariance: Vec<f64>,
}

channel!(
    /// `/estimate/odometry/maskukf`: MaskUKF's estimate with covariance.
    MaskUkfOdometry(Odometry), "/estimate/odometry/maskukf", "slidetrack.Odometry",
    derived::<Odometry>("slidetrack.Odometry")
);
channel!(
    /// `/estimate/odometry/roft`: ROFT's estimate with covariance.
    RoftOdometry(Odometry), "/estimate/odometry/roft", "slidetrack.Odometry",
    derived::<Odometry>("slidetrack.Odometry")
);
