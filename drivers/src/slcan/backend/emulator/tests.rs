//! [`SlcanBus`] end to end against the emulated adapter, through a real
//! pseudo-terminal.

use std::time::{Duration, Instant};

use slidetrack_core::TimeNs;

use super::*;
use crate::can::backend::socketcan::CanBus;
use crate::can::config::CanTactileConfig;
use crate::can::layout::CanLayoutDecoder;
use crate::can::protocol::XelaCanLayout;
use crate::io_error_kind::io_error_kind;
use crate::slcan::backend::SlcanBus;
use crate::slcan::protocol::SlcanConfig;

/// One frame per call whose data is the call's number, from 1, up to `limit`.
fn counting(limit: u32) -> FrameSource {
    let mut k = 0u32;
    Box::new(move || {
        if k >= limit {
            return None;
        }
        k += 1;
        Some(vec![CanFrame::standard(0x710 + k % 16, &k.to_be_bytes()).unwrap()])
    })
}

fn number(frame: &CanFrame) -> u32 {
    u32::from_be_bytes(frame.data().try_into().unwrap())
}

fn config() -> SlcanConfig {
    SlcanConfig { reply_timeout_ms: 2000, ..SlcanConfig::default() }
}

/// Waits up to 2 s for `done` to hold.
fn eventually(mut done: impl FnMut() -> bool) -> bool {
    let start = Instant::now();
    while start.elapsed() < Duration::from_secs(2) {
        if done() {
            return true;
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    false
}

fn commands(emulator: &SlcanEmulator) -> Vec<String> {
    emulator.record().commands
}

#[test]
fn the_adapter_is_set_up_and_its_frames_arrive_in_order_with_timestamps() {
    let emu_cfg = SlcanEmulatorConfig { clock_start_ms: 59_800, ..SlcanEmulatorConfig::default() };
    let emulator = SlcanEmulator::start(counting(10_000), emu_cfg).unwrap();
    let bus = SlcanBus::open(emulator.path(), &config()).unwrap();
    // `C` is refused (the channel was closed) and tolerated.
    assert_eq!(commands(&emulator), ["C", "S8", "Z1", "O"]);
    let record = emulator.record();
    assert_eq!(
        (record.open, record.bitrate_code, record.timestamps, record.refused),
        (true, Some(8), true, 1)
    );
    let first = bus.recv_timestamped(Duration::from_secs(2)).unwrap().expect("a frame");
    let (mut last, mut wrapped) = (first, false);
    assert_eq!(number(&first.frame), 1, "the source starts when the channel opens");
    for k in 2..=400 {
        let received = bus.recv_timestamped(Duration::from_secs(2)).unwrap().expect("a frame");
        assert_eq!(number(&received.frame), k, "frames in order, none lost");
        let (ts, previous) = (received.timestamp.expect("timestamps are on"), last.timestamp.unwrap());
        assert!(ts.adapter_ms >= previous.adapter_ms, "{ts:?} after {previous:?}");
        wrapped |= ts.raw_ms < previous.raw_ms;
        assert_eq!(bus.last_timestamp(), Some(ts));
        last = received;
    }
    let (first_ts, last_ts) = (first.timestamp.unwrap(), last.timestamp.unwrap());
    assert!(wrapped, "the clock opened 200 ms before its wrap");
    assert!(last_ts.adapter_ms >= 60_000, "{last_ts:?}");
    let adapter_span = last_ts.adapter_ms - first_ts.adapter_ms;
    let host_span = u64::try_from((last.received_at - first.received_at).as_millis()).unwrap();
    assert!(adapter_span.abs_diff(host_span) < 100, "adapter {adapter_span} ms, host {host_span} ms");
    let c = bus.counters();
    assert!(c.frames >= 400 && c.malformed == 0, "{c}");
}

#[test]
fn transmitted_frames_reach_the_adapter_and_drop_closes_the_channel() {
    for ack in [TransmitAck::Lawicel, TransmitAck::CarriageReturn] {
        let emu_cfg = SlcanEmulatorConfig { transmit_ack: ack, ..SlcanEmulatorConfig::default() };
        let emulator = SlcanEmulator::start(counting(u32::MAX), emu_cfg).unwrap();
        let bus = SlcanBus::open(emulator.path(), &config()).unwrap();
        let start = XelaCanLayout::default().start_command();
        let extended = CanFrame::new(0x1234_5678, true, &[1, 2, 3]).unwrap();
        bus.send(&start).unwrap();
        bus.send(&extended).unwrap();
        assert!(eventually(|| emulator.transmitted().len() == 2), "{:?}", emulator.record());
        assert_eq!(emulator.transmitted(), [start, extended]);
        assert_eq!(commands(&emulator)[4..], ["t20120700", "T123456783010203"]);
        // Frames keep coming around the acknowledgements.
        for _ in 0..50 {
            bus.recv(Duration::from_secs(2)).unwrap().expect("a frame");
        }
        assert_eq!(bus.counters().errors, 1, "only the initial `C` was refused");
        drop(bus);
        assert!(eventually(|| commands(&emulator).last().map(String::as_str) == Some("C")));
        assert!(!emulator.record().open);
    }
}

#[test]
fn an_unplugged_adapter_is_a_disconnection_that_sticks() {
    let emulator = SlcanEmulator::start(counting(u32::MAX), SlcanEmulatorConfig::default()).unwrap();
    let bus = SlcanBus::open(emulator.path(), &config()).unwrap();
    for _ in 0..20 {
        bus.recv(Duration::from_secs(2)).unwrap().expect("a frame");
    }
    emulator.unplug();
    let start = Instant::now();
    let e = loop {
        match bus.recv(Duration::from_millis(100)) {
            Ok(_) => assert!(start.elapsed() < Duration::from_secs(3), "still receiving after the unplug"),
            Err(e) => break e,
        }
    };
    assert_eq!(io_error_kind(&e), ErrorKind::Disconnected, "{e}");
    let again = bus.recv(Duration::from_millis(10)).unwrap_err();
    assert_eq!(io_error_kind(&again), ErrorKind::Disconnected, "{again}");
    let send = bus.send(&XelaCanLayout::default().start_command()).unwrap_err();
    assert_eq!(io_error_kind(&send), ErrorKind::Disconnected, "{send}");
}

#[test]
fn a_firmware_without_timestamps_is_named_and_tolerated_when_they_are_off() {
    let emu_cfg = || SlcanEmulatorConfig { timestamps_supported: false, ..SlcanEmulatorConfig::default() };
    let emulator = SlcanEmulator::start(counting(u32::MAX), emu_cfg()).unwrap();
    let e = SlcanBus::open(emulator.path(), &config()).err().expect("Z1 refused");
    assert_eq!(e.device, emulator.path());
    assert!(e.detail.contains("`Z1`") && e.detail.contains("timestamps = false"), "{e}");
    drop(emulator);
    let emulator = SlcanEmulator::start(counting(u32::MAX), emu_cfg()).unwrap();
    let bus = SlcanBus::open(emulator.path(), &SlcanConfig { timestamps: false, ..config() }).unwrap();
    assert_eq!(commands(&emulator), ["C", "S8", "Z0", "O"]);
    let received = bus.recv_timestamped(Duration::from_secs(2)).unwrap().unwrap();
    assert_eq!((number(&received.frame), received.timestamp), (1, None));
    assert_eq!(bus.last_timestamp(), None);
}

#[test]
fn an_adapter_left_open_is_used_as_it_is_without_setup() {
    let emu_cfg = SlcanEmulatorConfig { open_at_start: true, ..SlcanEmulatorConfig::default() };
    let emulator = SlcanEmulator::start(counting(u32::MAX), emu_cfg).unwrap();
    let bus = SlcanBus::open(emulator.path(), &SlcanConfig { setup: false, ..config() }).unwrap();
    let mut last = 0;
    for _ in 0..50 {
        let k = number(&bus.recv(Duration::from_secs(2)).unwrap().expect("a frame"));
        assert!(k > last, "{k} after {last}");
        last = k;
    }
    drop(bus);
    std::thread::sleep(Duration::from_millis(50));
    assert!(commands(&emulator).is_empty(), "no set-up, and no `C` on drop");
    // With set-up, an open adapter is closed first, then set up again.
    let bus = SlcanBus::open(emulator.path(), &config()).unwrap();
    assert_eq!(commands(&emulator), ["C", "S8", "Z1", "O"]);
    assert!(bus.recv_timestamped(Duration::from_secs(2)).unwrap().unwrap().timestamp.is_some());
}

#[test]
fn set_up_failures_say_what_and_where() {
    let e = SlcanBus::open("/dev/nonexistent-slcan", &SlcanConfig { bitrate: 300_000, ..config() })
        .err()
        .unwrap();
    assert_eq!(e.kind, ErrorKind::Other);
    assert!(e.detail.contains("300000"), "{e}");
    let e = SlcanBus::open("/dev/nonexistent-slcan", &config()).err().unwrap();
    assert_eq!(e.kind, ErrorKind::Disconnected, "{e}");
    // A terminal nobody answers on.
    let (_master, slave) = TTYPort::pair().unwrap();
    let path = slave.name().unwrap();
    let e = SlcanBus::open(&path, &SlcanConfig { reply_timeout_ms: 100, ..config() }).err().unwrap();
    assert_eq!((e.kind, e.device.as_str()), (ErrorKind::Timeout, path.as_str()));
    assert!(e.detail.contains("no reply to `C`"), "{e}");
}

/// A uSkin board behind the adapter: the start command goes out, scans
/// stream in and assemble, timed by the adapter's clock.
#[test]
fn a_xela_board_streams_scans_through_the_adapter() {
    let layout = XelaCanLayout::default();
    let mut scan = 0u16;
    let source: FrameSource = Box::new(move || {
        scan += 1;
        Some((0..layout.taxels).map(|t| layout.taxel_frame(t, [scan, t, 7], true)).collect())
    });
    let emu_cfg = SlcanEmulatorConfig { period: Duration::from_millis(2), ..SlcanEmulatorConfig::default() };
    let emulator = SlcanEmulator::start(source, emu_cfg).unwrap();
    let bus = SlcanBus::open(emulator.path(), &config()).unwrap();
    bus.send(&layout.start_command()).unwrap();
    let cfg = CanTactileConfig {
        sensors: crate::sensors::default_sensors(4, 4)[..1].to_vec(),
        ..CanTactileConfig::default()
    };
    let mut decoder = CanLayoutDecoder::new(cfg.layout().unwrap(), 500.0);
    let mut scans = Vec::new();
    while scans.len() < 50 {
        let received = bus.recv_timestamped(Duration::from_secs(2)).unwrap().expect("a frame");
        let t = TimeNs(received.timestamp.unwrap().adapter_ms * 1_000_000);
        scans.extend(decoder.push(t, &received.frame));
    }
    for pair in scans.windows(2) {
        let first = |s: &crate::can::layout::LayoutScan| s.taxels[0][0];
        assert_eq!(first(&pair[1]), first(&pair[0]) + 1, "consecutive scans");
        assert!(pair[1].t >= pair[0].t, "adapter times never decrease");
        assert_eq!(pair[1].taxels[15], [first(&pair[1]), 15, 7]);
    }
    assert_eq!(emulator.transmitted(), [layout.start_command()]);
}
