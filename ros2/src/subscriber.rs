//! [`StalledSubscriber`]: readers of ROS 2 topics that never read, the
//! worst subscriber a publisher can have (`bench --what collect-ros2`).

use rustdds::no_key::DataReader;
use rustdds::{DomainParticipant, QosPolicies, TopicKind};

use super::error::Ros2Error;
use super::names::{dds_topic, dds_type};
use super::payload::{CdrPayload, PlainCdrLe};
use super::qos::Profile;

/// A participant holding one reader per topic, never taking a sample.
pub struct StalledSubscriber {
    // Dropped in this order: the readers, then their participant.
    _readers: Vec<DataReader<CdrPayload, PlainCdrLe>>,
    _participant: DomainParticipant,
}

impl StalledSubscriber {
    /// Subscribes on `domain` to each `(ROS 2 topic, ROS 2 type)`, with the
    /// QoS the publisher offers ([`Profile::of`]).
    pub fn subscribe(domain: u16, topics: &[(&str, &str)]) -> Result<StalledSubscriber, Ros2Error> {
        let participant = DomainParticipant::new(domain)
            .map_err(|e| Ros2Error::Participant { domain, reason: e.to_string() })?;
        let subscriber = participant
            .create_subscriber(&QosPolicies::qos_none())
            .map_err(|e| Ros2Error::Participant { domain, reason: e.to_string() })?;
        let mut readers = Vec::new();
        for &(topic, ros_type) in topics {
            let failed = |what: &'static str, reason: String| Ros2Error::Endpoint {
                what,
                topic: topic.to_string(),
                ros_type: ros_type.to_string(),
                reason,
            };
            let qos = Profile::of(ros_type, topic).qos();
            let dds = participant
                .create_topic(dds_topic(topic), dds_type(ros_type), &qos, TopicKind::NoKey)
                .map_err(|e| failed("topic", e.to_string()))?;
            let reader = subscriber
                .create_datareader_no_key::<CdrPayload, PlainCdrLe>(&dds, Some(qos))
                .map_err(|e| failed("reader", e.to_string()))?;
            readers.push(reader);
        }
        Ok(StalledSubscriber { _readers: readers, _participant: participant })
    }
}
