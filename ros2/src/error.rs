//! [`Ros2Error`]: why the ROS 2 publisher or subscriber could not start.

/// Why ROS 2 publishing or subscribing failed.
#[derive(Debug, thiserror::Error)]
pub enum Ros2Error {
    /// The ROS 2 domain id is outside what DDS port mapping allows (0-232).
    #[error("ROS 2 domain id {domain} is out of range: DDS maps domains 0 to {max} to UDP ports")]
    Domain {
        /// The domain asked for.
        domain: u32,
        /// The largest usable domain.
        max: u32,
    },
    /// `ROS_DOMAIN_ID` is set but is not a number.
    #[error("ROS_DOMAIN_ID={value:?} is not a domain id (a number from 0 to 232)")]
    DomainEnv {
        /// The variable's value.
        value: String,
    },
    /// The DDS participant could not be created (sockets, ports).
    #[error("cannot join ROS 2 domain {domain} (DDS participant): {reason}")]
    Participant {
        /// The domain.
        domain: u16,
        /// RustDDS's reason.
        reason: String,
    },
    /// A DDS topic, publisher, subscriber, writer or reader could not be created.
    #[error("cannot create the DDS {what} for ROS 2 topic {topic} ({ros_type}): {reason}")]
    Endpoint {
        /// `topic`, `writer`, `reader`, ...
        what: &'static str,
        /// The ROS 2 topic (`/tactile/raw`).
        topic: String,
        /// The ROS 2 type (`slidetrack_msgs/msg/TactileRaw`).
        ros_type: String,
        /// RustDDS's reason.
        reason: String,
    },
    /// The publisher's thread could not start, or stopped before it was ready.
    #[error("the ROS 2 publisher thread: {0}")]
    Thread(String),
}
