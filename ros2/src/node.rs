//! [`Node`]: one DDS participant publishing the recorder's channels under
//! ROS 2 names, one writer per ROS 2 topic.

use std::collections::HashMap;

use rustdds::no_key::DataWriter;
use rustdds::{DomainParticipant, Publisher, QosPolicies, TopicKind};
use slidetrack_core::TimeNs;
use slidetrack_session::ros2::{convert, ros2_type};
use slidetrack_session::{LiveChannel, LiveRecord};

use super::error::Ros2Error;
use super::names::{dds_topic, dds_type};
use super::payload::{CdrPayload, PlainCdrLe};
use super::qos::Profile;

/// What the node published and could not publish.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct NodeStats {
    /// Messages handed to DDS.
    pub published: u64,
    /// Messages not published: their payload did not decode, or DDS refused them.
    pub failed: u64,
}

/// A session channel with a ROS 2 counterpart.
struct Route {
    schema: String,
    topic: String,
    ros_topic: String,
}

/// A DDS writer of one ROS 2 topic.
struct Writer {
    ros_type: &'static str,
    writer: DataWriter<CdrPayload, PlainCdrLe>,
}

/// A DDS participant and its ROS 2 writers.
pub(crate) struct Node {
    // Dropped in declaration order: the writers, their publisher, then the
    // participant (whose event loop removes the writers).
    writers: HashMap<String, Writer>,
    publisher: Publisher,
    participant: DomainParticipant,
    /// Channels by (recorder number, channel id); `None`: no ROS 2 counterpart.
    routes: HashMap<(u64, u16), Option<Route>>,
    stats: NodeStats,
}

impl Node {
    /// Joins `domain`.
    pub(crate) fn join(domain: u16) -> Result<Node, Ros2Error> {
        let participant = DomainParticipant::new(domain)
            .map_err(|e| Ros2Error::Participant { domain, reason: e.to_string() })?;
        let publisher = participant
            .create_publisher(&QosPolicies::qos_none())
            .map_err(|e| Ros2Error::Participant { domain, reason: e.to_string() })?;
        Ok(Node {
            participant,
            publisher,
            routes: HashMap::new(),
            writers: HashMap::new(),
            stats: NodeStats::default(),
        })
    }

    /// What was published so far.
    pub(crate) fn stats(&self) -> NodeStats {
        self.stats
    }

    /// Handles one record of the recorder's tap.
    pub(crate) fn handle(&mut self, record: LiveRecord) {
        match record {
            LiveRecord::Channel { session, id, channel } => {
                let route = self.route(&channel);
                self.routes.insert((session, id), route);
            }
            LiveRecord::Message { session, channel, log_time, payload, .. } => {
                self.publish(session, channel, log_time, &payload);
            }
            LiveRecord::SessionStarted { .. } | LiveRecord::SessionFinished { .. } => {}
        }
    }

    /// The route of a new channel, its writer created now so that
    /// subscribers discover it before its first message.
    fn route(&mut self, channel: &LiveChannel) -> Option<Route> {
        let (ros_type, ros_topic) = ros2_type(&channel.schema_name, &channel.topic)?;
        if let Some(w) = self.writers.get(ros_topic) {
            if w.ros_type != ros_type {
                tracing::warn!(
                    "ros2: {} ({}) is not published: {ros_topic} already carries {}",
                    channel.topic,
                    ros_type,
                    w.ros_type
                );
                return None;
            }
        } else {
            match self.writer(ros_type, ros_topic) {
                Ok(w) => {
                    self.writers.insert(ros_topic.to_string(), w);
                }
                Err(e) => {
                    tracing::warn!("ros2: {e}");
                    return None;
                }
            }
        }
        Some(Route {
            schema: channel.schema_name.clone(),
            topic: channel.topic.clone(),
            ros_topic: ros_topic.to_string(),
        })
    }

    fn writer(&self, ros_type: &'static str, ros_topic: &str) -> Result<Writer, Ros2Error> {
        let failed = |what: &'static str, reason: String| Ros2Error::Endpoint {
            what,
            topic: ros_topic.to_string(),
            ros_type: ros_type.to_string(),
            reason,
        };
        let profile = Profile::of(ros_type, ros_topic);
        let qos = profile.qos();
        let topic = self
            .participant
            .create_topic(dds_topic(ros_topic), dds_type(ros_type), &qos, TopicKind::NoKey)
            .map_err(|e| failed("topic", e.to_string()))?;
        let writer = self
            .publisher
            .create_datawriter_no_key::<CdrPayload, PlainCdrLe>(&topic, Some(qos))
            .map_err(|e| failed("writer", e.to_string()))?;
        tracing::debug!("ros2: publishing {ros_topic} ({ros_type}), QoS {}", profile.name());
        Ok(Writer { ros_type, writer })
    }

    fn publish(&mut self, session: u64, channel: u16, log_time: TimeNs, payload: &[u8]) {
        let Some(Some(route)) = self.routes.get(&(session, channel)) else { return };
        let Some(writer) = self.writers.get(&route.ros_topic) else { return };
        let message = match convert(&route.schema, &route.topic, log_time, payload) {
            Ok(Some(m)) => m,
            Ok(None) => return,
            Err(e) => {
                self.stats.failed += 1;
                tracing::debug!("ros2: a message of {} does not decode: {e}", route.topic);
                return;
            }
        };
        let Some(data) = CdrPayload::from_cdr(message.data) else {
            self.stats.failed += 1;
            return;
        };
        match writer.writer.write(data, None) {
            Ok(()) => self.stats.published += 1,
            Err(e) => {
                self.stats.failed += 1;
                tracing::debug!("ros2: {} not published: {e}", route.ros_topic);
            }
        }
    }
}
