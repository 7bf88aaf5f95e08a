//! The QoS of each ROS 2 topic: ROS 2's own profiles (`rmw/qos_profiles.h`).
//!
//! - sensor data (`rmw_qos_profile_sensor_data`): best effort, keep last 5,
//!   volatile. Tactile scans, hand state, images and camera info.
//! - default (`rmw_qos_profile_default`): reliable, keep last 10, volatile.
//!   Estimates.
//! - `/tf`: reliable, keep last 100, volatile, as `tf2_ros`'s
//!   `TransformBroadcaster` publishes it (`DynamicBroadcasterQoS`).

use rustdds::{Duration, QosPolicies, QosPolicyBuilder, policy};

/// Which ROS 2 QoS profile a topic uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Profile {
    /// Best effort, keep last 5.
    SensorData,
    /// Reliable, keep last 10.
    Default,
    /// Reliable, keep last 100 (`/tf`).
    Tf,
}

impl Profile {
    /// The profile of a ROS 2 type on a ROS 2 topic.
    pub fn of(ros_type: &str, topic: &str) -> Profile {
        if topic == "/tf" {
            Profile::Tf
        } else if ros_type.starts_with("sensor_msgs/")
            || matches!(ros_type, "slidetrack_msgs/msg/TactileRaw" | "slidetrack_msgs/msg/HandState")
        {
            Profile::SensorData
        } else {
            Profile::Default
        }
    }

    /// The DDS QoS of the profile.
    pub fn qos(self) -> QosPolicies {
        let (reliability, depth) = match self {
            Profile::SensorData => (policy::Reliability::BestEffort, 5),
            Profile::Default => (reliable(), 10),
            Profile::Tf => (reliable(), 100),
        };
        QosPolicyBuilder::new()
            .reliability(reliability)
            .history(policy::History::KeepLast { depth })
            .durability(policy::Durability::Volatile)
            .build()
    }

    /// Its name in the docs and logs.
    pub fn name(self) -> &'static str {
        match self {
            Profile::SensorData => "sensor data (best effort, keep last 5)",
            Profile::Default => "default (reliable, keep last 10)",
            Profile::Tf => "tf (reliable, keep last 100)",
        }
    }
}

/// Reliable; a writer waits at most 100 ms for room in its history (keep
/// last never waits: the oldest sample makes room).
fn reliable() -> policy::Reliability {
    policy::Reliability::Reliable { max_blocking_time: Duration::from_millis(100) }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sensors_are_best_effort_and_estimates_reliable() {
        assert_eq!(Profile::of("slidetrack_msgs/msg/TactileRaw", "/tactile/raw"), Profile::SensorData);
        assert_eq!(Profile::of("sensor_msgs/msg/CompressedImage", "/rgbd/color"), Profile::SensorData);
        assert_eq!(Profile::of("slidetrack_msgs/msg/SlidingEstimate", "/estimate/dekf"), Profile::Default);
        assert_eq!(Profile::of("tf2_msgs/msg/TFMessage", "/tf"), Profile::Tf);
        assert_eq!(Profile::SensorData.qos().reliability(), Some(policy::Reliability::BestEffort));
        assert_eq!(Profile::Default.qos().history(), Some(policy::History::KeepLast { depth: 10 }));
    }
}
