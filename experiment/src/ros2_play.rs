//! `play --ros2`: a recorded session published as ROS 2 topics at its
//! recorded timing, through the same publisher as `--ros2` on a recording
//! run (so the same topics, types and QoS: docs/ros2.md).

use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use anyhow::{Context, Result, bail};
use slidetrack_core::TimeNs;
use std::collections::HashMap;

use slidetrack_session::{ChannelDesc, LiveChannel, LiveSession, MessageReader, ReadOptions, SessionInfo};

use crate::outlets::{Ros2Stats, Ros2Topics};

/// How `play --ros2` plays.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ros2PlayOptions {
    /// The ROS 2 domain id (`None`: `ROS_DOMAIN_ID`, else 0).
    pub domain: Option<u32>,
    /// Playback speed: 1 at the recorded timing, 10 ten times as fast.
    pub rate: f64,
    /// Start again from the beginning at the end, until stopped.
    pub looping: bool,
    /// How long the topics are announced before the first message, so that
    /// subscribers discover the writers first (DDS discovery takes a
    /// moment, and sensor data is volatile: a message sent before a reader
    /// matched is not sent again).
    pub discovery: Duration,
}

impl Default for Ros2PlayOptions {
    fn default() -> Self {
        Ros2PlayOptions { domain: None, rate: 1.0, looping: false, discovery: Duration::from_secs(1) }
    }
}

/// What `play --ros2` did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Ros2PlayReport {
    /// Messages handed to the publisher.
    pub messages: u64,
    /// Times the end of the session was reached.
    pub endings: u32,
    /// What the publisher did with them.
    pub published: Ros2Stats,
}

/// The domain the topics are on, once joined (for the caller to say).
pub type OnJoined<'a> = &'a mut dyn FnMut(u16);

/// Publishes `file` as ROS 2 topics at its recorded timing (see
/// [`Ros2PlayOptions`]) until its end (or, looping, until `stop`).
pub fn play_ros2(
    file: &Path,
    options: &Ros2PlayOptions,
    stop: &AtomicBool,
    on_joined: OnJoined,
) -> Result<Ros2PlayReport> {
    if !(options.rate.is_finite() && options.rate > 0.0) {
        bail!("--rate must be a positive factor of the recorded timing, got {}", options.rate);
    }
    // The file first: a missing or unreadable one fails before the domain is joined.
    let info = SessionInfo::read(file, ReadOptions::default()).with_context(|| file.display().to_string())?;
    let topics = Ros2Topics::start(options.domain)?;
    on_joined(topics.domain());
    let mut report = Ros2PlayReport::default();
    while !stop.load(Ordering::SeqCst) {
        report.messages += play_once(file, &info, &topics, options, stop)?;
        if stop.load(Ordering::SeqCst) {
            break;
        }
        report.endings += 1;
        if !options.looping {
            break;
        }
    }
    report.published = topics.finish();
    Ok(report)
}

/// A channel as the publisher sees it. (It routes by topic and schema
/// name; the schema itself is not needed.)
fn live_channel(topic: &str, schema_name: &str, message_encoding: &str) -> LiveChannel {
    LiveChannel {
        topic: topic.into(),
        schema_name: schema_name.into(),
        schema_encoding: String::new(),
        schema_data: Vec::new(),
        message_encoding: message_encoding.into(),
        metadata: Default::default(),
    }
}

/// Plays `file` (summarised in `info`) once; the messages handed on.
fn play_once(
    file: &Path,
    info: &SessionInfo,
    topics: &Ros2Topics,
    options: &Ros2PlayOptions,
    stop: &AtomicBool,
) -> Result<u64> {
    let reader =
        MessageReader::open(file, &[], ReadOptions::default()).with_context(|| file.display().to_string())?;
    let mut session = LiveSession::start(topics.tap(), file.to_path_buf());
    // Every channel of the summary first, each numbered by its place there,
    // so that the writers exist (and are discovered) before the first message.
    let mut ids: HashMap<String, u16> = HashMap::new();
    for c in &info.channels {
        announce(&mut ids, &session, live_channel(&c.topic, &c.schema_name, &c.message_encoding));
    }
    sleep_unless_stopped(options.discovery, stop);
    let (started, mut first, mut messages) = (Instant::now(), None::<TimeNs>, 0);
    for m in reader {
        let m = m.with_context(|| file.display().to_string())?;
        let t0 = *first.get_or_insert(m.log_time);
        let due = Duration::from_secs_f64((m.log_time.0.saturating_sub(t0.0)) as f64 * 1e-9 / options.rate);
        if !sleep_unless_stopped(due.saturating_sub(started.elapsed()), stop) {
            break;
        }
        let id = match ids.get(m.topic()) {
            Some(&id) => id,
            None => {
                let ChannelDesc { topic, schema_name, message_encoding, .. } = m.channel.as_ref();
                announce(&mut ids, &session, live_channel(topic, schema_name, message_encoding))
            }
        };
        session.message(id, m.log_time, m.publish_time, m.sequence, m.data);
        messages += 1;
    }
    session.finished();
    Ok(messages)
}

/// Announces `channel` to `session` under the next id, noted in `ids`.
fn announce(ids: &mut HashMap<String, u16>, session: &LiveSession, channel: LiveChannel) -> u16 {
    let id = u16::try_from(ids.len()).unwrap_or(u16::MAX);
    ids.insert(channel.topic.clone(), id);
    session.channel(id, channel);
    id
}

/// Sleeps `wait` in steps short enough to notice `stop`; false when stopped.
fn sleep_unless_stopped(wait: Duration, stop: &AtomicBool) -> bool {
    let until = Instant::now() + wait;
    loop {
        if stop.load(Ordering::SeqCst) {
            return false;
        }
        let left = until.saturating_duration_since(Instant::now());
        if left.is_zero() {
            return true;
        }
        std::thread::sleep(left.min(Duration::from_millis(100)));
    }
}
