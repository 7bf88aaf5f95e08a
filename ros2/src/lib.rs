//! ROS 2 topics without a ROS installation: what a recorder writes,
//! published over DDS/RTPS by [RustDDS](https://docs.rs/rustdds) under ROS
//! 2's topic and type names (`rt/tactile/raw`,
//! `slidetrack_msgs::msg::dds_::TactileRaw_`), CDR-encoded by
//! [`slidetrack_session::ros2`], the encoder of `export --ros2-bag`.
//!
//! [`Ros2Publisher`] taps a recorder the way the live view does (a bounded
//! queue that drops when full, a thread at nice 19); [`qos`] gives each
//! topic ROS 2's default or sensor-data QoS. See `docs/ros2.md`.

mod domain;
mod error;
mod names;
mod node;
mod payload;
mod publisher;
pub mod qos;
mod subscriber;
pub mod xela;

pub use domain::{MAX_DOMAIN, domain_id};
pub use error::Ros2Error;
pub use names::{dds_topic, dds_type};
pub use node::NodeStats;
pub use payload::{CdrPayload, KeepBytes, NotCdrLe, PlainCdrLe};
pub use publisher::{Ros2Options, Ros2Publisher, Ros2Stats};
pub use subscriber::StalledSubscriber;
