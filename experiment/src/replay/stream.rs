//! One recorded channel read as a stream of typed messages, with bounded
//! memory, for the replay devices.

use std::marker::PhantomData;
use std::path::Path;

use serde::de::DeserializeOwned;
use slidetrack_core::{DeviceError, ErrorKind, TimeNs};
use slidetrack_session::{MessageReader, ReadOptions};

/// `e` and its causes on one line (a device error carries text, not a source).
fn chain(e: &dyn std::error::Error) -> String {
    let mut text = e.to_string();
    let mut source = e.source();
    while let Some(cause) = source {
        text = format!("{text}: {cause}");
        source = cause.source();
    }
    text
}

/// A message of a replayed channel with its recorded times and counter.
#[derive(Clone, Debug, PartialEq)]
pub struct Recorded<T> {
    /// Host acquisition time on the session clock.
    pub log_time: TimeNs,
    /// The device's timestamp, or the log time.
    pub publish_time: TimeNs,
    /// The device's frame counter (low 32 bits).
    pub sequence: u32,
    /// The decoded message.
    pub message: T,
}

/// The messages of one topic of a session, in file (log-time) order.
pub struct TopicStream<T> {
    reader: MessageReader,
    device: String,
    peeked: Option<Recorded<T>>,
    message: PhantomData<fn() -> T>,
}

impl<T: DeserializeOwned> TopicStream<T> {
    /// The messages of `topic` in the session at `path`; `device` names the
    /// replayed device in errors.
    pub fn open(path: &Path, topic: &str, device: &str) -> Result<TopicStream<T>, DeviceError> {
        let reader = MessageReader::open(path, &[topic], ReadOptions::default())
            .map_err(|e| DeviceError::new(ErrorKind::Other, device, chain(&e)))?;
        Ok(TopicStream { reader, device: device.to_string(), peeked: None, message: PhantomData })
    }

    /// The next message, `None` at the end of the recording.
    pub fn next_message(&mut self) -> Result<Option<Recorded<T>>, DeviceError> {
        if let Some(m) = self.peeked.take() {
            return Ok(Some(m));
        }
        let Some(raw) = self.reader.next() else { return Ok(None) };
        let raw = raw.map_err(|e| DeviceError::new(ErrorKind::Corrupt, &self.device, chain(&e)))?;
        let message = serde_json::from_slice(&raw.data).map_err(|e| {
            let detail = format!("{} at {}: {e}", raw.topic(), raw.log_time);
            DeviceError::new(ErrorKind::Corrupt, &self.device, detail)
        })?;
        Ok(Some(Recorded {
            log_time: raw.log_time,
            publish_time: raw.publish_time,
            sequence: raw.sequence,
            message,
        }))
    }

    /// The next message if it was logged at or before `t`.
    pub fn next_until(&mut self, t: TimeNs) -> Result<Option<Recorded<T>>, DeviceError> {
        match self.next_message()? {
            Some(m) if m.log_time <= t => Ok(Some(m)),
            Some(m) => {
                self.peeked = Some(m);
                Ok(None)
            }
            None => Ok(None),
        }
    }

    /// The message logged exactly at `t`, skipping older ones; `None` when
    /// there is none.
    pub fn at(&mut self, t: TimeNs) -> Result<Option<Recorded<T>>, DeviceError> {
        while let Some(m) = self.next_until(t)? {
            if m.log_time == t {
                return Ok(Some(m));
            }
        }
        Ok(None)
    }
}
