//! The serial backend end to end through a real pseudo-terminal.

use std::time::{Duration, Instant};

use slidetrack_core::{TactileInfo, TactileSample, TimeNs, WallClock};

use super::*;
use crate::sensors::HwSensor;
use crate::serial::config::SerialTactileConfig;
use slidetrack_core::{FingerReading, PerFinger, SensorLayout, TactileLayout};

/// Scans whose values tell their sequence number, one every `period`.
struct Counting {
    sequence: u64,
    period: Duration,
}

impl TactileSource for Counting {
    fn read(&mut self) -> Result<TactileSample, DeviceError> {
        std::thread::sleep(self.period);
        self.sequence += 1;
        Ok(TactileSample::new(TimeNs::ZERO, self.sequence, values(self.sequence)))
    }
    fn info(&self) -> TactileInfo {
        let sensors = ["a", "b", "c"].map(|n| SensorLayout::grid(n, "test", "thumb", 2, 2)).to_vec();
        TactileInfo {
            device: "counting".into(),
            rate_hz: 1000.0,
            layout: TactileLayout { sensors },
            fingers: PerFinger::from_fn(|_| FingerReading::mean("b")),
        }
    }
}

/// Scan `sequence`: three 2x2 sensors, every taxel distinct.
fn values(sequence: u64) -> Vec<RawTaxel> {
    let s = sequence as u16;
    (0..12).map(|t| [s, 100 * t, 7]).collect()
}

/// Sensors `a`, `b`, `c` on modules 3, 7 and 1, 2x2 taxels each.
fn hw_sensors(rows: u32) -> Vec<HwSensor> {
    [("a", 3), ("b", 7), ("c", 1)]
        .map(|(name, module)| HwSensor {
            name: name.into(),
            module,
            finger: "thumb".into(),
            model: "test".into(),
            rows,
            cols: 2,
            taxel_positions_mm: None,
        })
        .to_vec()
}

fn cfg(faults: EmulatorConfig) -> SerialTactileConfig {
    SerialTactileConfig {
        sensors: hw_sensors(2),
        fingers: Some(PerFinger::from_fn(|_| FingerReading::taxel("c", 3))),
        timeout_ms: 500,
        emulator: faults,
        ..SerialTactileConfig::default()
    }
}

fn start(faults: EmulatorConfig) -> EmulatedSerialTactile {
    let source = Box::new(Counting { sequence: 0, period: Duration::from_micros(500) });
    EmulatedSerialTactile::start(source, &cfg(faults), 1000.0, Arc::new(WallClock::start())).unwrap()
}

fn expected(sample: &TactileSample) -> Vec<RawTaxel> {
    values(sample.sequence)
}

#[test]
fn configured_sensors_must_match_the_simulated_ones() {
    let source = Box::new(Counting { sequence: 0, period: Duration::from_micros(500) });
    let c = SerialTactileConfig { sensors: hw_sensors(3), ..cfg(EmulatorConfig::default()) };
    let Err(e) = EmulatedSerialTactile::start(source, &c, 1000.0, Arc::new(WallClock::start())) else {
        panic!("3x2 sensors accepted for 2x2 simulated ones")
    };
    assert!(
        e.detail.contains("(a 3x2, b 3x2, c 3x2) must match the simulated sensors (a 2x2, b 2x2, c 2x2)"),
        "{e}"
    );
}

#[test]
fn scans_cross_a_real_tty_intact_and_in_order() {
    let mut tactile = start(EmulatorConfig::default());
    assert!(tactile.info().device.starts_with("/dev/"), "{}", tactile.info().device);
    let mut last_t = TimeNs::ZERO;
    for k in 1..=300u64 {
        let sample = tactile.read().unwrap();
        assert_eq!(sample.sequence, k);
        assert_eq!(sample.raw, expected(&sample));
        assert!(sample.t >= last_t);
        last_t = sample.t;
    }
    let c = tactile.counters().unwrap();
    assert!(c.frames >= 600, "{c}");
    assert_eq!(c.data_errors() + c.resyncs, 0, "{c}");
}

#[test]
fn injected_faults_lose_scans_but_never_corrupt_them() {
    let faults =
        EmulatorConfig { corrupt_every_frames: 9, garbage_every_frames: 7, ..EmulatorConfig::default() };
    let mut tactile = start(faults);
    let mut previous = 0;
    for _ in 0..300 {
        let sample = tactile.read().unwrap();
        assert!(sample.sequence > previous);
        assert_eq!(sample.raw, expected(&sample), "values of another scan");
        previous = sample.sequence;
    }
    let c = tactile.counters().unwrap();
    assert!(c.crc_errors > 20 && c.resyncs > 20 && c.gaps > 20 && c.incomplete_scans > 20, "{c}");
    assert!(previous > 330, "the corrupt frames cost their scans: {previous}");
}

#[test]
fn unplugging_the_device_is_a_disconnection_that_sticks() {
    let faults = EmulatorConfig { unplug_after_s: Some(0.2), ..EmulatorConfig::default() };
    let mut tactile = start(faults);
    let start = Instant::now();
    let e = loop {
        match tactile.read() {
            Ok(_) => assert!(start.elapsed() < Duration::from_secs(5), "still reading after the unplug"),
            Err(e) => break e,
        }
    };
    assert_eq!(e.kind, ErrorKind::Disconnected, "{e}");
    assert!(e.device.starts_with("/dev/"), "{e}");
    assert_eq!(tactile.read().unwrap_err().kind, ErrorKind::Disconnected);
}

#[test]
fn a_silent_device_times_out() {
    let source = Box::new(Counting { sequence: 0, period: Duration::from_millis(400) });
    let mut c = cfg(EmulatorConfig::default());
    c.startup_timeout_ms = 100;
    c.timeout_ms = 100;
    let mut tactile = EmulatedSerialTactile::start(source, &c, 1000.0, Arc::new(WallClock::start())).unwrap();
    let e = tactile.read().unwrap_err();
    assert_eq!(e.kind, ErrorKind::Timeout);
    assert!(e.detail.contains("no data"), "{e}");
    // A timeout is not final: the scan comes later.
    let sample = (0..10).find_map(|_| tactile.read().ok()).expect("a scan after the timeouts");
    assert_eq!(sample.sequence, 1);
}
