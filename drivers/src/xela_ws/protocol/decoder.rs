//! The stateful side of the protocol: counters, the message counter's gaps
//! and the check of the sensors the rig is configured with.

use slidetrack_core::DecoderCounters;
use thiserror::Error;

use super::error::XelaParseError;
use super::message::{XelaEvent, XelaScan};
use super::parse::parse_message;

/// A sensor the rig expects the server to report.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ExpectedSensor {
    /// Its number (its key in the messages: the position xServ.ini gives it).
    pub sensor: u32,
    /// Its model, as xServ.ini's `model` names it (`uSPa44`); compared
    /// without regard to letter case, as the server may report `USPA35`.
    pub model: String,
    /// Its number of taxels (`uSPa44`: 16).
    pub taxels: usize,
}

/// The sensors the rig is configured with. Sensors the server reports
/// beyond these are accepted and passed on.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Expected {
    /// The expected sensors.
    pub sensors: Vec<ExpectedSensor>,
}

impl Expected {
    /// Checks `scan` against the expectation: every expected sensor present,
    /// of its model, with its number of taxels.
    pub fn check(&self, scan: &XelaScan) -> Result<(), XelaMismatch> {
        for want in &self.sensors {
            let Some(got) = scan.sensor(want.sensor) else {
                return Err(XelaMismatch::MissingSensor {
                    sensor: want.sensor,
                    configured_model: want.model.clone(),
                    received: scan.sensors.iter().map(|s| s.sensor).collect(),
                });
            };
            if !got.model.eq_ignore_ascii_case(&want.model) {
                return Err(XelaMismatch::Model {
                    sensor: want.sensor,
                    configured: want.model.clone(),
                    received: got.model.clone(),
                });
            }
            if got.taxels.len() != want.taxels {
                return Err(XelaMismatch::Taxels {
                    sensor: want.sensor,
                    model: got.model.clone(),
                    configured: want.taxels,
                    received: got.taxels.len(),
                });
            }
        }
        Ok(())
    }
}

/// A data message that does not match the configured sensors: the server's
/// configuration (xServ.ini) and the rig's disagree.
#[derive(Clone, Debug, Error, PartialEq, Eq)]
pub enum XelaMismatch {
    /// An expected sensor is not in the message.
    #[error(
        "sensor {sensor} ({configured_model}) is configured but the server sends sensors {received:?}: \
         check `num_of_sensor` and the [sensorN] sections of xServ.ini"
    )]
    MissingSensor {
        /// The expected sensor's number.
        sensor: u32,
        /// Its configured model.
        configured_model: String,
        /// The sensor numbers the message carries.
        received: Vec<u32>,
    },
    /// A sensor of another model.
    #[error(
        "sensor {sensor} is configured as model {configured} but the server reports {received}: \
         set `model` in xServ.ini (section {section}) or the rig's expected model"
    , section = ini_section(.sensor))]
    Model {
        /// The sensor's number.
        sensor: u32,
        /// The configured model.
        configured: String,
        /// The model the server reports.
        received: String,
    },
    /// A sensor with another number of taxels.
    #[error(
        "sensor {sensor} ({model}) is configured with {configured} taxels but the server sends {received}: \
         set `model` in xServ.ini (section {section}) or the rig's expected taxel count"
    , section = ini_section(.sensor))]
    Taxels {
        /// The sensor's number.
        sensor: u32,
        /// The model the server reports.
        model: String,
        /// The configured number of taxels.
        configured: usize,
        /// The number the server sends.
        received: usize,
    },
}

/// The xServ.ini section that configures sensor `n`: `[sensor]` holds the
/// first sensor's settings and every sensor's defaults, `[sensorN]` overrides
/// them for sensor N ≥ 2.
fn ini_section(n: &u32) -> String {
    if *n <= 1 { "[sensor]".into() } else { format!("[sensor{n}], defaults from [sensor]") }
}

/// A break in the server's message counter between two data messages.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum MessageGap {
    /// The counter jumped forward: messages were lost (sent while the
    /// client was disconnected, dropped by the server, or malformed).
    Skip {
        /// The counter that would have followed the previous message.
        expected: u64,
        /// The counter received.
        got: u64,
    },
    /// The same counter again.
    Repeat {
        /// The repeated counter.
        message: u64,
    },
    /// The counter went back: it wrapped, or the server restarted.
    Backward {
        /// The previous counter.
        previous: u64,
        /// The counter received.
        got: u64,
    },
}

/// What a [`XelaDecoder`] (and a client's connection) has seen. Every
/// counter only grows.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct XelaCounters {
    /// Messages decoded (text and binary, good or not).
    pub messages: u64,
    /// Welcome messages.
    pub welcomes: u64,
    /// Data messages decoded into scans.
    pub scans: u64,
    /// Messages that were not a welcome nor a well-formed data message
    /// (skipped).
    pub malformed: u64,
    /// Data messages that did not match the configured sensors.
    pub mismatches: u64,
    /// Breaks in the message counter (each [`MessageGap`]).
    pub gaps: u64,
    /// Counters skipped over by forward gaps: messages lost.
    pub lost_messages: u64,
    /// Repeated counters.
    pub repeats: u64,
    /// Counters that went back (wrap or server restart).
    pub backward: u64,
    /// Connections re-established after a loss (client only).
    pub reconnects: u64,
}

impl XelaCounters {
    /// The counters in the form every tactile decoder records
    /// (`/tactile/decoder`): scans as `frames`, counter breaks as `gaps`,
    /// malformed messages (dropped scans) as `incomplete_scans`.
    pub fn decoder_counters(&self) -> DecoderCounters {
        DecoderCounters {
            frames: self.scans,
            gaps: self.gaps,
            incomplete_scans: self.malformed,
            ..DecoderCounters::default()
        }
    }
}

impl std::fmt::Display for XelaCounters {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} messages ({} scans, {} welcomes, {} malformed, {} mismatched), {} gaps ({} lost, {} repeated, \
             {} backward), {} reconnects",
            self.messages,
            self.scans,
            self.welcomes,
            self.malformed,
            self.mismatches,
            self.gaps,
            self.lost_messages,
            self.repeats,
            self.backward,
            self.reconnects
        )
    }
}

/// A decoded message and the gap it follows, if any.
#[derive(Clone, Debug, PartialEq)]
pub struct Decoded {
    /// The message.
    pub event: XelaEvent,
    /// The break in the message counter before this data message.
    pub gap: Option<MessageGap>,
}

/// Why a message gave no scan.
#[derive(Clone, Debug, Error, PartialEq, Eq)]
pub enum XelaError {
    /// Not a welcome nor a well-formed data message: skip it.
    #[error("malformed message: {0}")]
    Malformed(#[from] XelaParseError),
    /// A well-formed data message from a server configured otherwise than the rig.
    #[error("{0}")]
    Mismatch(#[from] XelaMismatch),
}

/// Decodes the messages of one server, in order, without I/O.
///
/// # Contract
/// - [`decode`](Self::decode) takes each text message once, in arrival
///   order; any text is accepted and nothing panics.
/// - A malformed message is an error that costs only itself: it is counted
///   and the next message decodes as if it had not come (its counter, if
///   it had one, is unknown, so the next scan shows a gap).
/// - A data message that does not match the [`Expected`] sensors is a
///   [`XelaError::Mismatch`]; it is counted and does not move the counter.
/// - Each data message's counter should follow the previous data message's
///   by one; any other step is reported with the scan as a [`MessageGap`]
///   and counted. Welcomes leave the counter alone, so a reconnection to a
///   server that kept counting shows the messages missed while away.
#[derive(Clone, Debug, Default)]
pub struct XelaDecoder {
    expected: Option<Expected>,
    last_message: Option<u64>,
    counters: XelaCounters,
}

impl XelaDecoder {
    /// A decoder checking data messages against `expected`, if given.
    pub fn new(expected: Option<Expected>) -> XelaDecoder {
        XelaDecoder { expected, last_message: None, counters: XelaCounters::default() }
    }

    /// Decodes one text message.
    pub fn decode(&mut self, text: &str) -> Result<Decoded, XelaError> {
        self.counters.messages += 1;
        let event = parse_message(text).inspect_err(|_| self.counters.malformed += 1)?;
        let XelaEvent::Data(scan) = event else {
            self.counters.welcomes += 1;
            return Ok(Decoded { event, gap: None });
        };
        if let Some(expected) = &self.expected
            && let Err(mismatch) = expected.check(&scan)
        {
            self.counters.mismatches += 1;
            return Err(mismatch.into());
        }
        let gap = self.follow(scan.message);
        self.counters.scans += 1;
        Ok(Decoded { event: XelaEvent::Data(scan), gap })
    }

    /// Counts a binary message (the server sends only text) of `bytes`
    /// bytes as malformed and returns its error.
    pub fn reject_binary(&mut self, bytes: usize) -> XelaError {
        self.counters.messages += 1;
        self.counters.malformed += 1;
        XelaParseError::Binary { bytes }.into()
    }

    /// The counters so far.
    pub fn counters(&self) -> XelaCounters {
        self.counters
    }

    /// The counter of the last data message decoded.
    pub fn last_message(&self) -> Option<u64> {
        self.last_message
    }

    /// The expected sensors, if any.
    pub fn expected(&self) -> Option<&Expected> {
        self.expected.as_ref()
    }

    fn follow(&mut self, message: u64) -> Option<MessageGap> {
        let previous = self.last_message.replace(message)?;
        let expected = previous.wrapping_add(1);
        let gap = if message == expected {
            return None;
        } else if message == previous {
            self.counters.repeats += 1;
            MessageGap::Repeat { message }
        } else if message > expected {
            self.counters.lost_messages += message - expected;
            MessageGap::Skip { expected, got: message }
        } else {
            self.counters.backward += 1;
            MessageGap::Backward { previous, got: message }
        };
        self.counters.gaps += 1;
        Some(gap)
    }
}
