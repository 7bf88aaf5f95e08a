//! [`XelaRos2Tactile`]: the rig's tactile source subscribed to
//! `xela_server_ros2`'s `SensStream` topic over DDS (RustDDS), every taxel
//! of the configured sensors kept in the server's order.

use std::sync::Arc;
use std::time::{Duration, Instant};

use rustdds::no_key::DataReader;
use rustdds::{DomainParticipant, QosPolicyBuilder, TopicKind, policy};
use slidetrack_core::{
    Clock, DecoderCounters, DeviceError, ErrorKind, TactileInfo, TactileSample, TactileSource, TimeNs,
};

use super::sens_stream::{SENS_STREAM_TYPE, SensStream};
use crate::error::Ros2Error;
use crate::names::{dds_topic, dds_type};
use crate::payload::{CdrPayload, PlainCdrLe};

/// A sensor the rig expects in each `SensStream`.
#[derive(Clone, Debug, PartialEq)]
pub struct WantedSensor {
    /// Its `sensor_pos` (the server's sensor number, 1, 2, ...).
    pub sensor_pos: u8,
    /// The model the server must report (compared without letter case).
    pub model: String,
    /// Taxels the server must send for it.
    pub taxels: usize,
}

/// Where and what to subscribe.
#[derive(Clone, Debug)]
pub struct XelaRos2Options {
    /// DDS domain id.
    pub domain: u16,
    /// The ROS 2 topic (`/xServTopic`).
    pub topic: String,
    /// The sensors, in the layout's order.
    pub sensors: Vec<WantedSensor>,
    /// Longest wait for a scan once streaming.
    pub timeout: Duration,
    /// Longest wait for the first scan (discovery included).
    pub startup_timeout: Duration,
}

/// How often an idle read looks for a sample.
const POLL: Duration = Duration::from_millis(1);

/// Samples the reader keeps before the oldest is dropped (the server's
/// writer keeps 10).
const READER_DEPTH: i32 = 100;

/// Sensors read from `xela_server_ros2` (see `docs/ros2.md`).
pub struct XelaRos2Tactile {
    // Dropped in this order: the reader, then its participant.
    reader: DataReader<CdrPayload, PlainCdrLe>,
    _participant: DomainParticipant,
    options: XelaRos2Options,
    info: TactileInfo,
    clock: Arc<dyn Clock>,
    started: bool,
    last_t: TimeNs,
    last_message: Option<u32>,
    counters: DecoderCounters,
}

impl XelaRos2Tactile {
    /// Joins the domain and subscribes to the topic (reliable, as the
    /// server's rclpy publisher offers, keep last [`READER_DEPTH`]).
    pub fn subscribe(
        options: XelaRos2Options,
        info: TactileInfo,
        clock: Arc<dyn Clock>,
    ) -> Result<XelaRos2Tactile, Ros2Error> {
        let domain = options.domain;
        let participant = DomainParticipant::new(domain)
            .map_err(|e| Ros2Error::Participant { domain, reason: e.to_string() })?;
        let failed = |what: &'static str, reason: String| Ros2Error::Endpoint {
            what,
            topic: options.topic.clone(),
            ros_type: SENS_STREAM_TYPE.to_string(),
            reason,
        };
        let qos = QosPolicyBuilder::new()
            .reliability(policy::Reliability::Reliable {
                max_blocking_time: rustdds::Duration::from_millis(100),
            })
            .history(policy::History::KeepLast { depth: READER_DEPTH })
            .durability(policy::Durability::Volatile)
            .build();
        let subscriber =
            participant.create_subscriber(&qos).map_err(|e| failed("subscriber", e.to_string()))?;
        let topic = participant
            .create_topic(dds_topic(&options.topic), dds_type(SENS_STREAM_TYPE), &qos, TopicKind::NoKey)
            .map_err(|e| failed("topic", e.to_string()))?;
        let reader = subscriber
            .create_datareader_no_key::<CdrPayload, PlainCdrLe>(&topic, Some(qos))
            .map_err(|e| failed("reader", e.to_string()))?;
        Ok(XelaRos2Tactile {
            reader,
            _participant: participant,
            options,
            info,
            clock,
            started: false,
            last_t: TimeNs::ZERO,
            last_message: None,
            counters: DecoderCounters::default(),
        })
    }

    fn device(&self) -> String {
        format!("ROS 2 topic {} (domain {})", self.options.topic, self.options.domain)
    }

    /// The sample of `scan`: the configured sensors in their order.
    fn sample(&mut self, scan: &SensStream) -> Result<TactileSample, String> {
        check_sensors(&self.options.sensors, scan)?;
        let mut raw = Vec::with_capacity(self.info.layout.taxel_count());
        let mut forces = Some(Vec::with_capacity(raw.capacity()));
        let mut first = None;
        for want in &self.options.sensors {
            let Some(got) = scan.sensors.iter().find(|s| s.sensor_pos == want.sensor_pos) else { continue };
            first.get_or_insert(got);
            raw.extend_from_slice(&got.taxels);
            match &mut forces {
                Some(all) if got.forces.len() == got.taxels.len() => {
                    all.extend(got.forces.iter().map(|f| f.map(f64::from)));
                }
                _ => forces = None,
            }
        }
        let message = first.map_or(0, |s| s.message);
        if self.last_message.is_some_and(|m| message != m.wrapping_add(1)) {
            self.counters.gaps += 1;
        }
        self.last_message = Some(message);
        let t = self.clock.now().max(self.last_t);
        self.last_t = t;
        let mut sample = TactileSample::new(t, u64::from(message), raw);
        sample.device_time_s = first.map(|s| s.time_s);
        sample.calibrated_n = forces;
        Ok(sample)
    }
}

/// Every wanted sensor in `scan`, of its model and taxel count.
pub fn check_sensors(sensors: &[WantedSensor], scan: &SensStream) -> Result<(), String> {
    for (i, want) in sensors.iter().enumerate() {
        let Some(got) = scan.sensors.iter().find(|s| s.sensor_pos == want.sensor_pos) else {
            let sent: Vec<u8> = scan.sensors.iter().map(|s| s.sensor_pos).collect();
            return Err(format!(
                "hw.tactile.sensors[{i}].sensor = {} but xela_server_ros2 sends sensor_pos {sent:?}",
                want.sensor_pos
            ));
        };
        if !got.model.eq_ignore_ascii_case(&want.model) {
            return Err(format!(
                "hw.tactile.sensors[{i}].model = {} but xela_server_ros2 sends {} for sensor_pos {}",
                want.model, got.model, want.sensor_pos
            ));
        }
        if got.taxels.len() != want.taxels {
            return Err(format!(
                "hw.tactile.sensors[{i}] has {} taxels but xela_server_ros2 sends {} for sensor_pos {}",
                want.taxels,
                got.taxels.len(),
                want.sensor_pos
            ));
        }
    }
    Ok(())
}

impl TactileSource for XelaRos2Tactile {
    /// # Contract
    /// - Blocks until the next `SensStream` and returns its scan of the
    ///   configured sensors; the time is the session time when it was
    ///   taken from the reader, `sequence` the server's `message` counter
    ///   (breaks counted as gaps), `device_time_s` the server's `time`,
    ///   `calibrated_n` the forces when every sensor carries one per taxel.
    /// - Samples that do not decode are counted (`incomplete_scans`) and skipped.
    /// - `Timeout` when no scan arrives within the timeout (the first:
    ///   the startup timeout); `Other` when the server sends other sensors
    ///   than configured.
    fn read(&mut self) -> Result<TactileSample, DeviceError> {
        let limit = if self.started { self.options.timeout } else { self.options.startup_timeout };
        let deadline = Instant::now() + limit;
        loop {
            match self.reader.take_next_sample() {
                Ok(Some(s)) => match SensStream::decode(s.value().bytes()) {
                    Ok(scan) => {
                        let sample = self
                            .sample(&scan)
                            .map_err(|d| DeviceError::new(ErrorKind::Other, self.device(), d))?;
                        self.counters.frames += 1;
                        self.started = true;
                        return Ok(sample);
                    }
                    Err(e) => {
                        self.counters.incomplete_scans += 1;
                        tracing::debug!("{}: {e}", self.device());
                    }
                },
                Ok(None) if Instant::now() >= deadline => {
                    let why = format!("no SensStream within {} ms", limit.as_millis());
                    return Err(DeviceError::new(ErrorKind::Timeout, self.device(), why));
                }
                Ok(None) => std::thread::sleep(POLL),
                Err(e) => {
                    // A sample RustDDS could not hand over (not CDR_LE).
                    self.counters.incomplete_scans += 1;
                    tracing::debug!("{}: {e}", self.device());
                }
            }
        }
    }

    fn info(&self) -> TactileInfo {
        self.info.clone()
    }

    fn counters(&self) -> Option<DecoderCounters> {
        Some(self.counters)
    }
}
