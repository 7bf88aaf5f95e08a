//! The rig's tactile source over `xela_server`: an [`XelaWsClient`] whose
//! scans become [`TactileSample`]s of the configured sensors.

use std::sync::Arc;
use std::time::Duration;

use slidetrack_core::{
    Clock, DecoderCounters, DeviceError, ErrorKind, TactileInfo, TactileSample, TactileSource, TimeNs,
};

use super::client::{ReconnectPolicy, XelaReceived, XelaWsClient, XelaWsOptions};
use crate::xela_ws::config::{XelaSensor, XelaWsTactileConfig};
use crate::xela_ws::protocol::XelaScan;

/// Sensors read through `xela_server` (see `docs/protocols.md`).
pub struct XelaWsTactile {
    client: XelaWsClient,
    info: TactileInfo,
    sensors: Vec<XelaSensor>,
    clock: Arc<dyn Clock>,
    timeout: Duration,
    startup_timeout: Duration,
    started: bool,
    last_t: TimeNs,
    failed: Option<DeviceError>,
}

/// The client options of `cfg`. The sensors are checked by the source,
/// which names the settings, not by the client.
pub fn client_options(cfg: &XelaWsTactileConfig) -> XelaWsOptions {
    let r = &cfg.reconnect;
    XelaWsOptions {
        expected: None,
        connect_timeout: Duration::from_millis(cfg.connect_timeout_ms),
        reconnect: ReconnectPolicy {
            initial_backoff: Duration::from_millis(r.initial_backoff_ms),
            max_backoff: Duration::from_millis(r.max_backoff_ms),
            max_attempts: r.max_attempts,
            max_duration: Duration::from_millis(r.max_duration_ms),
        },
        ..XelaWsOptions::default()
    }
}

impl XelaWsTactile {
    /// Connects to `url` (retrying as `cfg.reconnect` allows); sample times
    /// are taken on `clock` when each message arrives.
    pub fn connect(
        url: &str,
        cfg: &XelaWsTactileConfig,
        rate_hz: f64,
        clock: Arc<dyn Clock>,
    ) -> Result<XelaWsTactile, DeviceError> {
        let client = XelaWsClient::connect(url, client_options(cfg))?;
        Ok(XelaWsTactile {
            client,
            info: cfg.info(url, rate_hz),
            sensors: cfg.sensors.clone(),
            clock,
            timeout: Duration::from_millis(cfg.timeout_ms),
            startup_timeout: Duration::from_millis(cfg.startup_timeout_ms.max(cfg.timeout_ms)),
            started: false,
            last_t: TimeNs::ZERO,
            failed: None,
        })
    }

    /// The client's counters (messages, malformed, gaps, reconnections).
    pub fn xela_counters(&self) -> crate::xela_ws::protocol::XelaCounters {
        self.client.counters()
    }

    /// The sample of `received`: the configured sensors in their order,
    /// stamped with the arrival time on the session clock.
    fn sample(&mut self, received: &XelaReceived) -> Result<TactileSample, DeviceError> {
        check_sensors(&self.sensors, &received.scan)
            .map_err(|detail| DeviceError::new(ErrorKind::Other, self.client.url(), detail))?;
        let scan = &received.scan;
        let mut raw = Vec::with_capacity(self.info.layout.taxel_count());
        let mut forces = Some(Vec::with_capacity(raw.capacity()));
        for s in &self.sensors {
            // check_sensors found every configured sensor.
            let Some(got) = scan.sensor(s.sensor) else { continue };
            raw.extend_from_slice(&got.taxels);
            match (&mut forces, &got.calibrated) {
                (Some(all), Some(f)) => all.extend_from_slice(f),
                _ => forces = None,
            }
        }
        let age = received.arrival.elapsed();
        let now = self.clock.now();
        let t = TimeNs(now.0.saturating_sub(age.as_nanos() as u64)).max(self.last_t);
        self.last_t = t;
        let mut sample = TactileSample::new(t, scan.message, raw);
        sample.device_time_s = scan.server_time_s;
        sample.calibrated_n = forces;
        Ok(sample)
    }
}

/// Every configured sensor in `scan`, of its model and taxel count; the
/// error names the setting at fault.
pub fn check_sensors(sensors: &[XelaSensor], scan: &XelaScan) -> Result<(), String> {
    for (i, want) in sensors.iter().enumerate() {
        let Some(got) = scan.sensor(want.sensor) else {
            let sent: Vec<u32> = scan.sensors.iter().map(|s| s.sensor).collect();
            return Err(format!(
                "hw.tactile.sensors[{i}].sensor = {} but xela_server sends sensors {sent:?} \
                 (num_of_sensor and the [sensorN] sections of xServ.ini)",
                want.sensor
            ));
        };
        if !got.model.eq_ignore_ascii_case(&want.model) {
            return Err(format!(
                "hw.tactile.sensors[{i}].model = {} but xela_server sends {} for sensor {} \
                 (`model` in xServ.ini, or the rig's model)",
                want.model, got.model, want.sensor
            ));
        }
        if got.taxels.len() != want.taxels() {
            return Err(format!(
                "hw.tactile.sensors[{i}] has {} x {} = {} taxels but xela_server sends {} for sensor {} ({})",
                want.rows,
                want.cols,
                want.taxels(),
                got.taxels.len(),
                want.sensor,
                got.model
            ));
        }
    }
    Ok(())
}

impl TactileSource for XelaWsTactile {
    /// # Contract
    /// - Blocks until the next data message and returns its scan of the
    ///   configured sensors; the sample time is the session time when the
    ///   message was read from the socket, `sequence` the server's message
    ///   counter (its breaks counted as gaps), `device_time_s` the server's
    ///   `time`, `calibrated_n` the forces when every sensor carries them.
    /// - Malformed messages are counted (`incomplete_scans`) and skipped.
    /// - `Timeout` when no scan arrives within `timeout_ms` (the first:
    ///   `startup_timeout_ms`) on an open connection. A lost connection is
    ///   re-established within the call as `reconnect` allows (the call
    ///   blocks meanwhile: a short outage is bridged, its messages counted
    ///   as a gap); `Disconnected` when the server stays gone beyond the
    ///   policy, after which every call fails; `Other` (also final) when the server sends
    ///   other sensors than configured.
    fn read(&mut self) -> Result<TactileSample, DeviceError> {
        if let Some(e) = &self.failed {
            return Err(e.clone());
        }
        let limit = if self.started { self.timeout } else { self.startup_timeout };
        let received = loop {
            match self.client.next_scan(limit) {
                Ok(r) => break r,
                // Reconnecting: the policy decides, not the scan timeout.
                Err(e) if e.kind == ErrorKind::Timeout && !self.client.connected() => {
                    tracing::debug!("{e}");
                }
                Err(e) if e.kind == ErrorKind::Timeout => return Err(e),
                Err(e) => {
                    self.failed = Some(e.clone());
                    return Err(e);
                }
            }
        };
        let sample = self.sample(&received).inspect_err(|e| self.failed = Some(e.clone()))?;
        self.started = true;
        Ok(sample)
    }

    fn info(&self) -> TactileInfo {
        self.info.clone()
    }

    fn counters(&self) -> Option<DecoderCounters> {
        Some(self.client.counters().decoder_counters())
    }
}

#[cfg(test)]
mod tests;
