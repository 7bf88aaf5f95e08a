//! The source against the scripted emulator, and its configuration.

use std::time::Duration;

use slidetrack_core::{ConfigError, ErrorKind, SimClock, parse_toml};

use super::*;
use crate::config::{HwRigConfig, TactileDevice};
use crate::xela_ws::backend::emulator::{XelaWsEmulator, XelaWsEmulatorConfig, synthetic_scans};
use crate::xela_ws::protocol::{ExpectedSensor, WireStyle, encode_scan};

const TWO_PATCHES: &str = r#"
[tactile]
kind = "xela_ws"
url = "ws://127.0.0.1:5000"
timeout_ms = 500
reconnect = { initial_backoff_ms = 5, max_backoff_ms = 20, max_attempts = 3, max_duration_ms = 200 }
fingers = { thumb = { sensor = "left" }, index = { sensor = "right", taxel = 5 }, middle = { sensor = "right" } }
[[tactile.sensors]]
name = "left"
sensor = 1
finger = "thumb"
model = "uSPa44"
rows = 4
cols = 4
[[tactile.sensors]]
name = "right"
sensor = 2
finger = "index"
model = "uSPa44"
rows = 4
cols = 4
"#;

fn config(text: &str) -> Result<XelaWsTactileConfig, String> {
    let hw: HwRigConfig = parse_toml(text, "rig.toml").map_err(|e: ConfigError| e.to_string())?;
    hw.validate().map_err(|e| e.to_string())?;
    let TactileDevice::XelaWs(x) = hw.tactile else { panic!("not xela_ws: {:?}", hw.tactile) };
    Ok(x)
}

fn expected(n: u32) -> Vec<ExpectedSensor> {
    (1..=n).map(|sensor| ExpectedSensor { sensor, model: "uSPa44".into(), taxels: 16 }).collect()
}

fn source(texts: Vec<String>, cfg: &XelaWsTactileConfig) -> (XelaWsEmulator, XelaWsTactile) {
    let emulator = XelaWsEmulator::start(XelaWsEmulatorConfig::texts(texts, Duration::from_millis(2)))
        .expect("emulator");
    let clock: Arc<dyn Clock> = Arc::new(SimClock::new());
    let source = XelaWsTactile::connect(&emulator.url(), cfg, 100.0, clock).expect("connected");
    (emulator, source)
}

#[test]
fn the_table_parses_and_mistakes_name_the_setting() {
    let cfg = config(TWO_PATCHES).unwrap();
    assert_eq!(cfg.sensors.iter().map(|s| (s.sensor, s.taxels())).collect::<Vec<_>>(), [(1, 16), (2, 16)]);
    assert_eq!(cfg.info("x", 100.0).layout.taxel_count(), 32);
    assert_eq!(client_options(&cfg).reconnect.max_attempts, 3);
    let defaults = config("[tactile]\nkind = \"xela_ws\"\n").unwrap();
    assert_eq!(defaults, XelaWsTactileConfig::default());
    assert_eq!(defaults.url, "ws://127.0.0.1:5000");

    let zero = TWO_PATCHES.replace("sensor = 2\n", "sensor = 0\n");
    assert!(config(&zero).unwrap_err().contains("hw.tactile.sensors `right` has sensor = 0"));
    let shared = TWO_PATCHES.replace("sensor = 2\n", "sensor = 1\n");
    assert!(config(&shared).unwrap_err().contains("`left` and `right`"));
    let backoff = TWO_PATCHES.replace("max_backoff_ms = 20", "max_backoff_ms = 1");
    assert!(config(&backoff).unwrap_err().contains("hw.tactile.reconnect.max_backoff_ms = 1"));
    let typo = TWO_PATCHES.replace("timeout_ms = 500", "timeout = 500");
    assert!(config(&typo).unwrap_err().contains("timeout"));
}

#[test]
fn a_scan_keeps_every_taxel_the_message_counter_the_server_time_and_whole_forces() {
    let cfg = config(TWO_PATCHES).unwrap();
    let mut scans = synthetic_scans(40, 3, &expected(3), true);
    // Scan 41: sensor 2 without forces, so the scan has none; scan 42 skips a counter.
    scans[1].sensors[1].calibrated = None;
    scans[2].message = 43;
    let texts = scans.iter().map(|s| encode_scan(s, WireStyle::IntegerList)).collect();
    let (_emulator, mut source) = source(texts, &cfg);
    let got: Vec<TactileSample> = (0..3).map(|_| source.read().unwrap()).collect();
    for (sample, scan) in got.iter().zip(&scans) {
        // Sensors 1 and 2 in the configured order; the server's sensor 3 is not configured.
        let want: Vec<_> = scan.sensors[..2].iter().flat_map(|s| s.taxels.clone()).collect();
        assert_eq!(sample.raw, want);
        assert_eq!((sample.sequence, sample.device_time_s), (scan.message, scan.server_time_s));
    }
    let forces: Vec<_> = scans[0].sensors[..2].iter().flat_map(|s| s.calibrated.clone().unwrap()).collect();
    assert_eq!(got[0].calibrated_n.as_ref(), Some(&forces));
    assert_eq!(got[1].calibrated_n, None, "forces of some sensors only: none");
    let c = source.counters().unwrap();
    assert_eq!((c.frames, c.gaps, c.incomplete_scans), (3, 1, 0));
}

#[test]
fn malformed_messages_are_counted_and_a_wrong_taxel_count_is_final() {
    let cfg = config(TWO_PATCHES).unwrap();
    let mut scans = synthetic_scans(1, 2, &expected(2), false);
    scans[1].sensors[1].taxels.truncate(15);
    let mut texts: Vec<String> = scans.iter().map(|s| encode_scan(s, WireStyle::HexString)).collect();
    texts.insert(1, "{\"message\": 2, \"1\": {".into());
    let (_emulator, mut source) = source(texts, &cfg);
    source.read().unwrap();
    let e = source.read().unwrap_err();
    assert_eq!(e.kind, ErrorKind::Other);
    assert_eq!(
        e.detail,
        "hw.tactile.sensors[1] has 4 x 4 = 16 taxels but xela_server sends 15 for sensor 2 (uSPa44)"
    );
    assert_eq!(source.read().unwrap_err(), e, "final");
    assert_eq!(source.counters().unwrap().incomplete_scans, 1);
}

#[test]
fn a_server_gone_beyond_the_policy_is_disconnected() {
    let cfg = config(TWO_PATCHES).unwrap();
    let texts = synthetic_scans(1, 3, &expected(2), false)
        .iter()
        .map(|s| encode_scan(s, WireStyle::IntegerList))
        .collect();
    let mut script = XelaWsEmulatorConfig::texts(texts, Duration::from_millis(2));
    script.disconnect_after = vec![2];
    script.accept_reconnect = false;
    let emulator = XelaWsEmulator::start(script).expect("emulator");
    let clock: Arc<dyn Clock> = Arc::new(SimClock::new());
    let mut source = XelaWsTactile::connect(&emulator.url(), &cfg, 100.0, clock).unwrap();
    source.read().unwrap();
    source.read().unwrap();
    let e = source.read().unwrap_err();
    assert_eq!(e.kind, ErrorKind::Disconnected, "{e}");
    assert_eq!(source.read().unwrap_err().kind, ErrorKind::Disconnected);
}
