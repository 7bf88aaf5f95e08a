//! The publisher thread: records of the recorders' tap to Foxglove channels.

use std::collections::HashMap;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use crossbeam_channel::Receiver;
use foxglove::{ChannelBuilder, Context, PartialMetadata, RawChannel, Schema, SinkId, WebSocketServerHandle};
use slidetrack_session::{LiveChannel, LiveReceiver, LiveRecord};

/// Schemas whose messages `image_max_hz` throttles.
const IMAGE_SCHEMAS: &[&str] = &["foxglove.CompressedImage", "foxglove.RawImage", "foxglove.CompressedVideo"];

/// How long the publisher waits for a record before it looks at the stop flag.
const POLL: Duration = Duration::from_millis(50);

/// Counts of the publisher.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct PublisherStats {
    pub(crate) published: u64,
    pub(crate) images_throttled: u64,
}

/// A viewer that has just subscribed to `topic`.
pub(crate) struct NewSubscriber {
    pub(crate) topic: String,
    pub(crate) sink: SinkId,
}

/// A Foxglove channel and what it was made from.
struct Published {
    spec: Arc<LiveChannel>,
    channel: Arc<RawChannel>,
    /// The latest message sent (log time ns, payload), for new subscribers.
    latest: Option<(u64, Vec<u8>)>,
    /// Least wall time between two messages sent, for images.
    min_interval: Option<Duration>,
    last_sent: Option<Instant>,
}

pub(crate) struct Publisher {
    context: Arc<Context>,
    server: Arc<WebSocketServerHandle>,
    image_min_interval: Option<Duration>,
    /// Channels by topic, kept across sessions.
    by_topic: HashMap<String, Published>,
    /// The current session and its channel ids' topics.
    session: Option<u64>,
    topics: HashMap<u16, String>,
    subscribed: Receiver<NewSubscriber>,
    stats: PublisherStats,
}

impl Publisher {
    pub(crate) fn new(
        context: Arc<Context>,
        server: Arc<WebSocketServerHandle>,
        image_max_hz: f64,
        subscribed: Receiver<NewSubscriber>,
    ) -> Publisher {
        let image_min_interval = (image_max_hz.is_finite() && image_max_hz > 0.0)
            .then(|| Duration::from_secs_f64(1.0 / image_max_hz));
        Publisher {
            context,
            server,
            image_min_interval,
            by_topic: HashMap::new(),
            session: None,
            topics: HashMap::new(),
            subscribed,
            stats: PublisherStats::default(),
        }
    }

    /// Publishes until `stop` is set or every tap is gone; what is still
    /// queued then is left for [`Publisher::catch_up`].
    pub(crate) fn run(&mut self, rx: &LiveReceiver, stop: &AtomicBool) {
        while !stop.load(Ordering::Acquire) {
            self.send_latest_to_new_subscribers();
            match rx.recv_timeout(POLL) {
                Ok(Some(record)) => self.handle(record),
                Ok(None) => {}
                Err(_closed) => break,
            }
        }
    }

    /// Publishes everything queued now, without waiting; whether there was anything.
    pub(crate) fn catch_up(&mut self, rx: &LiveReceiver) -> bool {
        let mut any = self.send_latest_to_new_subscribers();
        while let Ok(Some(record)) = rx.recv_timeout(Duration::ZERO) {
            self.handle(record);
            any = true;
        }
        any
    }

    /// Counts so far.
    pub(crate) fn stats(&self) -> PublisherStats {
        self.stats
    }

    fn handle(&mut self, record: LiveRecord) {
        match record {
            LiveRecord::SessionStarted { session, path } => {
                if self.session.is_some() {
                    // The new session's clock starts again: viewers drop what they hold.
                    self.server.clear_session(None);
                }
                tracing::debug!("live: session {session}, {}", path.display());
                self.session = Some(session);
                self.topics.clear();
                for published in self.by_topic.values_mut() {
                    published.latest = None;
                }
            }
            LiveRecord::Channel { session, id, channel } if Some(session) == self.session => {
                self.topics.insert(id, channel.topic.clone());
                self.advertise(channel);
            }
            LiveRecord::Message { session, channel, log_time, payload, .. }
                if Some(session) == self.session =>
            {
                let Some(published) = self.topics.get(&channel).and_then(|t| self.by_topic.get_mut(t)) else {
                    return;
                };
                let now = Instant::now();
                if let (Some(min), Some(last)) = (published.min_interval, published.last_sent)
                    && now.duration_since(last) < min
                {
                    self.stats.images_throttled += 1;
                    return;
                }
                published.last_sent = Some(now);
                published.channel.log_with_meta(&payload, PartialMetadata { log_time: Some(log_time.0) });
                published.latest = Some((log_time.0, payload));
                self.stats.published += 1;
            }
            LiveRecord::SessionFinished { session } if Some(session) == self.session => {
                self.topics.clear();
            }
            _ => {}
        }
    }

    /// Sends each new subscriber the latest message of its channel (it may
    /// also have had it already, when it subscribed just before); whether
    /// anyone had subscribed.
    fn send_latest_to_new_subscribers(&mut self) -> bool {
        let mut any = false;
        while let Ok(NewSubscriber { topic, sink }) = self.subscribed.try_recv() {
            any = true;
            if let Some(Published { channel, latest: Some((t, payload)), .. }) = self.by_topic.get(&topic) {
                channel.log_with_meta_to_sink(payload, PartialMetadata { log_time: Some(*t) }, Some(sink));
            }
        }
        any
    }

    /// Makes (or keeps) the Foxglove channel of `spec`.
    fn advertise(&mut self, spec: Arc<LiveChannel>) {
        if self.by_topic.get(&spec.topic).is_some_and(|p| p.spec == spec) {
            return;
        }
        if let Some(old) = self.by_topic.remove(&spec.topic) {
            old.channel.close();
        }
        let schema = (!spec.schema_name.is_empty() || !spec.schema_encoding.is_empty()).then(|| {
            Schema::new(spec.schema_name.as_str(), spec.schema_encoding.as_str(), spec.schema_data.clone())
        });
        let built = ChannelBuilder::new(spec.topic.as_str())
            .message_encoding(spec.message_encoding.as_str())
            .schema(schema)
            .metadata(spec.metadata.clone())
            .context(&self.context)
            .build_raw();
        match built {
            Ok(channel) => {
                let image = IMAGE_SCHEMAS.contains(&spec.schema_name.as_str());
                let min_interval = if image { self.image_min_interval } else { None };
                let published = Published {
                    spec: Arc::clone(&spec),
                    channel,
                    latest: None,
                    min_interval,
                    last_sent: None,
                };
                self.by_topic.insert(spec.topic.clone(), published);
            }
            Err(e) => tracing::warn!("live: cannot publish {}: {e}", spec.topic),
        }
    }
}
