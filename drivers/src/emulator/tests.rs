//! The serial backend end to end through a real pseudo-terminal.

use std::time::{Duration, Instant};

use slidetrack_core::{TimeNs, WallClock};

use super::*;
use crate::config::SerialTactileConfig;

/// Scans whose values tell their sequence number, one every `period`.
struct Counting {
    sequence: u64,
    period: Duration,
}

impl TactileSource for Counting {
    fn read(&mut self) -> Result<TactileSample, DeviceError> {
        std::thread::sleep(self.period);
        self.sequence += 1;
        let s = self.sequence as u16;
        Ok(TactileSample {
            t: TimeNs::ZERO,
            sequence: self.sequence,
            raw: [[s, 0, 7], [s, 100, 7], [s, 200, 7]],
        })
    }
    fn info(&self) -> TactileInfo {
        TactileInfo { device: "counting".into(), rate_hz: 1000.0, taxels: None }
    }
}

fn cfg(faults: EmulatorConfig) -> SerialTactileConfig {
    SerialTactileConfig {
        fingers: PerFinger {
            thumb: TaxelRef { module: 0, taxel: 3 },
            index: TaxelRef { module: 1, taxel: 0 },
            middle: TaxelRef { module: 1, taxel: 15 },
        },
        timeout_ms: 500,
        emulator: faults,
        ..SerialTactileConfig::default()
    }
}

fn start(faults: EmulatorConfig) -> EmulatedSerialTactile {
    let source = Box::new(Counting { sequence: 0, period: Duration::from_micros(500) });
    EmulatedSerialTactile::start(source, &cfg(faults), 1000.0, Arc::new(WallClock::start())).unwrap()
}

fn expected(sample: &TactileSample) -> [RawTaxel; 3] {
    let s = sample.sequence as u16;
    [[s, 0, 7], [s, 100, 7], [s, 200, 7]]
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
