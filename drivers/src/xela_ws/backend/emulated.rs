//! `url = "emulated"`: the simulated rig's sensors served by a local
//! [`XelaWsEmulator`] in `xela_server`'s JSON and read back by the real
//! client and source (closed loop with the simulated hand), with faults.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use crossbeam_channel::{Sender, bounded};
use slidetrack_core::{Clock, DeviceError, ErrorKind, TactileSample, TactileSource};

use super::emulator::{LiveMessage, XelaWsEmulator};
use super::source::XelaWsTactile;
use crate::emulated::{Emulated, check_emulated_sensors};
use crate::xela_ws::config::{EMULATED_URL, XelaEmulatorConfig, XelaWsTactileConfig};
use crate::xela_ws::protocol::{XelaScan, XelaSensorScan, encode_scan, encode_welcome};

/// The source reading the emulator; dropping it closes the connection,
/// then stops the feed and the server.
pub type EmulatedXelaWsTactile = Emulated<XelaWsTactile, XelaWsLiveEmulator>;

struct FeedThread {
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl Drop for FeedThread {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        if let Some(t) = self.thread.take()
            && t.join().is_err()
        {
            tracing::warn!("xela_server emulator: the feed thread panicked");
        }
    }
}

impl Emulated<XelaWsTactile, XelaWsLiveEmulator> {
    /// Starts a local server fed with `source`'s scans (`cfg.emulator`'s
    /// encoding and faults), connects the source to it (`cfg` as for a real
    /// server, its `url` ignored).
    pub fn start(
        source: Box<dyn TactileSource>,
        cfg: &XelaWsTactileConfig,
        rate_hz: f64,
        clock: Arc<dyn Clock>,
    ) -> Result<EmulatedXelaWsTactile, DeviceError> {
        // Connected before the first scan is made, so that none is lost.
        let (emulator, tactile) =
            XelaWsLiveEmulator::serve(source, cfg, |url| XelaWsTactile::connect(url, cfg, rate_hz, clock))?;
        Ok(Emulated::new(tactile, emulator))
    }
}

/// The server alone, fed with a source's scans, for clients of other
/// programs (`slidetrack emulate xela-server`): scans made while no client
/// is connected are lost, as with the real server.
pub struct XelaWsLiveEmulator {
    feed: Option<FeedThread>,
    server: XelaWsEmulator,
}

impl XelaWsLiveEmulator {
    /// Starts a local server fed with `source`'s scans, encoded as
    /// `cfg.sensors` and `cfg.emulator` say.
    pub fn start(
        source: Box<dyn TactileSource>,
        cfg: &XelaWsTactileConfig,
    ) -> Result<XelaWsLiveEmulator, DeviceError> {
        Ok(XelaWsLiveEmulator::serve(source, cfg, |_| Ok(()))?.0)
    }

    /// Starts the server, calls `before_feed` with its URL (a client that
    /// must see every scan connects there), then starts feeding it.
    fn serve<T>(
        source: Box<dyn TactileSource>,
        cfg: &XelaWsTactileConfig,
        before_feed: impl FnOnce(&str) -> Result<T, DeviceError>,
    ) -> Result<(XelaWsLiveEmulator, T), DeviceError> {
        let grids: Vec<_> = cfg.sensors.iter().map(|s| (s.name.as_str(), s.rows, s.cols)).collect();
        check_emulated_sensors(&source.info(), &grids, EMULATED_URL)?;
        let fail = |e: std::io::Error| {
            DeviceError::new(ErrorKind::Other, EMULATED_URL, format!("cannot start the emulator: {e}"))
        };
        // A few scans of slack: the feed blocks (and the simulated rig
        // waits) rather than run ahead of the server.
        let (tx, rx) = bounded(8);
        let server = XelaWsEmulator::start_live(Some(encode_welcome(Some("slidetrack-emulator"))), rx)
            .map_err(fail)?;
        let before = before_feed(&server.url())?;
        let stop = Arc::new(AtomicBool::new(false));
        let feed = Feed::new(source, cfg, tx, Arc::clone(&stop));
        let thread = std::thread::Builder::new()
            .name("xela-ws-feed".into())
            .spawn(move || feed.run())
            .map_err(fail)?;
        Ok((XelaWsLiveEmulator { feed: Some(FeedThread { stop, thread: Some(thread) }), server }, before))
    }

    /// The URL clients connect to (`ws://127.0.0.1:PORT`).
    pub fn url(&self) -> String {
        self.server.url()
    }
}

impl Drop for XelaWsLiveEmulator {
    fn drop(&mut self) {
        // The feed stops before the server so that it never blocks on a full channel.
        self.feed.take();
    }
}

/// Turns the simulated scans into the server's messages.
struct Feed {
    source: Box<dyn TactileSource>,
    /// Per sensor of the source: server number, reported model, taxels in a scan.
    sensors: Vec<(u32, String, std::ops::Range<usize>)>,
    faults: XelaEmulatorConfig,
    tx: Sender<LiveMessage>,
    stop: Arc<AtomicBool>,
}

impl Feed {
    fn new(
        source: Box<dyn TactileSource>,
        cfg: &XelaWsTactileConfig,
        tx: Sender<LiveMessage>,
        stop: Arc<AtomicBool>,
    ) -> Feed {
        let last = cfg.sensors.len().saturating_sub(1);
        let ranges: Vec<_> = source.info().layout.sensor_ranges().map(|(_, r)| r).collect();
        let sensors = cfg
            .sensors
            .iter()
            .zip(ranges)
            .enumerate()
            .map(|(i, (s, r))| {
                let model = match &cfg.emulator.wrong_model {
                    Some(m) if i == last => m.clone(),
                    _ => s.model.clone(),
                };
                (s.sensor, model, r)
            })
            .collect();
        Feed { source, sensors, faults: cfg.emulator.clone(), tx, stop }
    }

    fn send(&self, m: LiveMessage) -> bool {
        let mut m = m;
        loop {
            if self.stop.load(Ordering::SeqCst) {
                return false;
            }
            match self.tx.send_timeout(m, Duration::from_millis(20)) {
                Ok(()) => return true,
                Err(crossbeam_channel::SendTimeoutError::Timeout(back)) => m = back,
                Err(crossbeam_channel::SendTimeoutError::Disconnected(_)) => return false,
            }
        }
    }

    fn run(mut self) {
        let style = self.faults.encoding.wire_style();
        let disconnect_after = self.faults.disconnect_after_s.map(Duration::from_secs_f64);
        let mut first: Option<Instant> = None;
        let mut message = 0u64;
        let mut scans = 0u64;
        while !self.stop.load(Ordering::SeqCst) {
            if let (Some(start), Some(after)) = (first, disconnect_after)
                && start.elapsed() >= after
                && self.faults.disconnect_after_s.take().is_some()
            {
                tracing::info!("xela_server emulator: dropping the connection");
                let down = self.faults.down_for_s.map(Duration::from_secs_f64);
                if !self.send(LiveMessage::Disconnect(down)) {
                    return;
                }
            }
            let sample = match self.source.read() {
                Ok(s) => s,
                Err(e) => {
                    tracing::warn!("xela_server emulator: the simulated source failed: {e}");
                    return;
                }
            };
            first.get_or_insert_with(Instant::now);
            scans += 1;
            message += 1;
            let text = encode_scan(&self.scan(message, &sample), style);
            let every = |n: u32| n > 0 && scans.is_multiple_of(u64::from(n));
            let malformed = every(self.faults.malformed_every).then(|| text[..text.len() / 2].to_string());
            if !self.send(LiveMessage::Text(text)) {
                return;
            }
            if let Some(broken) = malformed
                && !self.send(LiveMessage::Text(broken))
            {
                return;
            }
            if every(self.faults.gap_every) {
                message += 1;
            }
        }
    }

    fn scan(&self, message: u64, sample: &TactileSample) -> XelaScan {
        let unix_s = SystemTime::now().duration_since(UNIX_EPOCH).map_or(0.0, |d| d.as_secs_f64());
        let sensors = self
            .sensors
            .iter()
            .map(|(number, model, range)| XelaSensorScan {
                sensor: *number,
                model: model.clone(),
                time_s: Some(unix_s),
                taxels: sample.raw.get(range.clone()).unwrap_or(&[]).to_vec(),
                calibrated: None,
            })
            .collect();
        XelaScan { message, server_time_s: Some(unix_s), sensors }
    }
}
