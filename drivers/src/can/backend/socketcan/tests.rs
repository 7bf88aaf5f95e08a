//! The CAN backends on an in-memory bus, and on `vcan` when the machine has one.

use std::collections::VecDeque;
use std::sync::Mutex;

use slidetrack_core::{HandActuator, WallClock};

use super::bus_errors::BusProblem;
use super::*;
use crate::can::backend::CanTactile;
use crate::can::config::CanTactileConfig;
use std::sync::Arc;

use crate::can::layout::{PayloadFormat, ValidityByte};
use crate::can::protocol::XelaCanLayout;
use crate::can_hand::backend::CanHand;
use crate::can_hand::config::CanHandConfig;
use crate::can_hand::protocol::{HandMessage, HandState};
use crate::sensors::HwSensor;
use slidetrack_core::{ActuatorCommand, Clock, ErrorKind, TactileSource};
use slidetrack_core::{FingerReading, PerFinger};

/// A bus in memory: records what is sent, serves queued frames, and can
/// vanish (every call then fails with `ENODEV`).
#[derive(Default)]
struct MemoryBus {
    sent: Mutex<Vec<CanFrame>>,
    incoming: Mutex<VecDeque<CanFrame>>,
    gone: std::sync::atomic::AtomicBool,
}

impl MemoryBus {
    fn queue(&self, frames: impl IntoIterator<Item = CanFrame>) {
        self.incoming.lock().unwrap().extend(frames);
    }
    fn sent(&self) -> Vec<CanFrame> {
        self.sent.lock().unwrap().clone()
    }
    fn unplug(&self) {
        self.gone.store(true, std::sync::atomic::Ordering::SeqCst);
    }
    fn check(&self) -> io::Result<()> {
        if self.gone.load(std::sync::atomic::Ordering::SeqCst) {
            return Err(io::Error::from_raw_os_error(nix::errno::Errno::ENODEV as i32));
        }
        Ok(())
    }
}

impl CanBus for MemoryBus {
    fn send(&self, frame: &CanFrame) -> io::Result<()> {
        self.sent.lock().unwrap().push(*frame);
        self.check()
    }
    fn recv(&self, timeout: Duration) -> io::Result<Option<CanFrame>> {
        self.check()?;
        if let Some(f) = self.incoming.lock().unwrap().pop_front() {
            return Ok(Some(f));
        }
        std::thread::sleep(timeout.min(Duration::from_millis(2)));
        Ok(None)
    }
    fn name(&self) -> &str {
        "mem0"
    }
}

fn sensor(name: &str, module: u32, rows: u32, cols: u32) -> HwSensor {
    HwSensor {
        name: name.into(),
        module,
        finger: "thumb".into(),
        model: "test".into(),
        rows,
        cols,
        taxel_positions_mm: None,
    }
}

fn tactile_cfg() -> CanTactileConfig {
    CanTactileConfig {
        taxels: 32,
        taxels_per_module: 16,
        // A 1x4 strip on module 0 (board taxels 0-3), a 2x5 patch on module 1 (16-25).
        sensors: vec![sensor("strip", 0, 1, 4), sensor("patch", 1, 2, 5)],
        fingers: Some(PerFinger {
            thumb: FingerReading::taxel("strip", 2),
            index: FingerReading::taxel("patch", 0),
            middle: FingerReading::mean("patch"),
        }),
        timeout_ms: 30,
        startup_timeout_ms: 30,
        // The legacy drivers' status byte, checked only because it is configured.
        payload: PayloadFormat {
            valid: Some(ValidityByte { byte: 0, below: 250 }),
            ..PayloadFormat::default()
        },
        ..CanTactileConfig::default()
    }
}

fn scan_frames(l: &XelaCanLayout, scan: u16, invalid: Option<u16>) -> Vec<CanFrame> {
    (0..l.taxels).map(|t| l.taxel_frame(t, [scan, t, 5], Some(t) != invalid)).collect()
}

#[test]
fn the_board_is_started_and_its_scans_read_through_the_finger_map() {
    let bus = Arc::new(MemoryBus::default());
    let cfg = tactile_cfg();
    let l = cfg.legacy_layout();
    for s in 0..3 {
        bus.queue(scan_frames(&l, s, if s == 1 { Some(25) } else { None }));
    }
    let mut tactile = CanTactile::with_bus(bus.clone(), &cfg, 100.0, Arc::new(WallClock::start())).unwrap();
    assert_eq!(bus.sent(), vec![l.start_command()]);
    let a = tactile.read().unwrap();
    let board: Vec<u16> = (0..4).chain(16..26).collect();
    assert_eq!(a.sequence, 0);
    assert_eq!(a.raw, board.iter().map(|&t| [0, t, 5]).collect::<Vec<_>>(), "every taxel of both sensors");
    // Scan 1's board taxel 25 (the patch's last) was invalid: dropped, counted.
    let b = tactile.read().unwrap();
    assert_eq!((b.sequence, b.raw[0]), (2, [2, 0, 5]));
    let c = tactile.counters().unwrap();
    assert_eq!((c.frames, c.invalid_samples, c.incomplete_scans), (42, 1, 1), "only mapped ids count");
    let info = tactile.info();
    assert_eq!((info.layout.taxel_count(), info.fingers), (14, cfg.fingers.clone().unwrap()));
    let e = tactile.read().unwrap_err();
    assert_eq!(e.kind, ErrorKind::Timeout);
    assert!(e.detail.contains("no complete scan"), "{e}");
    bus.unplug();
    assert_eq!(tactile.read().unwrap_err().kind, ErrorKind::Disconnected);
    assert_eq!(tactile.read().unwrap_err().kind, ErrorKind::Disconnected, "it sticks");
}

#[test]
fn a_silent_board_times_out_with_the_ids_it_waited_for() {
    let bus = Arc::new(MemoryBus::default());
    let mut tactile = CanTactile::with_bus(bus, &tactile_cfg(), 100.0, Arc::new(WallClock::start())).unwrap();
    let e = tactile.read().unwrap_err();
    assert_eq!(e.kind, ErrorKind::Timeout);
    assert!(e.detail.contains("first id 0x710, 14 ids"), "{e}");
}

fn hand_cfg() -> CanHandConfig {
    CanHandConfig { heartbeat_ms: 5, max_volts: 4.0, ..CanHandConfig::default() }
}

fn decode_all(bus: &MemoryBus) -> Vec<HandMessage> {
    let ids = hand_cfg().ids();
    bus.sent().iter().filter_map(|f| ids.decode(f).unwrap()).collect()
}

#[test]
fn the_hand_gets_saturated_set_points_heartbeats_and_a_release_on_drop() {
    let bus = Arc::new(MemoryBus::default());
    let mut hand = CanHand::with_bus(bus.clone(), &hand_cfg()).unwrap();
    hand.command(&ActuatorCommand::FingerVolts([1.0, -9.0, f64::NAN])).unwrap();
    std::thread::sleep(Duration::from_millis(40));
    hand.command(&ActuatorCommand::FingerVolts([0.5, 0.5, 0.5])).unwrap();
    drop(hand);
    let messages = decode_all(&bus);
    let setpoints: Vec<_> = messages.iter().filter(|m| matches!(m, HandMessage::Setpoint { .. })).collect();
    assert_eq!(
        setpoints,
        [
            &HandMessage::Setpoint { counter: 0, volts: [1.0, -4.0, 0.0] },
            &HandMessage::Setpoint { counter: 1, volts: [0.5, 0.5, 0.5] },
        ]
    );
    let beats = messages.iter().filter(|m| matches!(m, HandMessage::Heartbeat { .. })).count();
    assert!(beats >= 4, "{beats} heartbeats in 40 ms at 5 ms");
    assert!(
        messages.iter().any(|m| matches!(m, HandMessage::Heartbeat { state: HandState::Commanding, .. }))
    );
    assert_eq!(messages.last(), Some(&HandMessage::Release), "released on drop, heartbeat stopped");
}

#[test]
fn a_vanished_bus_fails_the_command_and_still_tries_to_release() {
    let bus = Arc::new(MemoryBus::default());
    let mut hand = CanHand::with_bus(bus.clone(), &hand_cfg()).unwrap();
    hand.command(&ActuatorCommand::FingerVolts([1.0; 3])).unwrap();
    bus.unplug();
    let e = hand.command(&ActuatorCommand::FingerVolts([2.0; 3])).unwrap_err();
    assert_eq!(e.kind, ErrorKind::Disconnected, "{e}");
    assert!(bus.sent().iter().any(|f| f.id == 0x302), "a release was sent after the failure");
    assert_eq!(
        hand.command(&ActuatorCommand::FingerVolts([0.0; 3])).unwrap_err().kind,
        ErrorKind::Disconnected
    );
    assert!(hand.release().is_err(), "the release is attempted and its failure reported");
}

/// Runs on the `vcan` interface named in `SLIDETRACK_VCAN` (create one with
/// `sudo ip link add dev vcan0 type vcan && sudo ip link set up vcan0`).
#[test]
#[cfg_attr(not(slidetrack_vcan), ignore = "needs a vcan interface named in SLIDETRACK_VCAN")]
fn the_tactile_board_and_the_hand_work_on_vcan() {
    let name = std::env::var("SLIDETRACK_VCAN").expect("SLIDETRACK_VCAN names the vcan interface");
    let board = SocketCanBus::open(&name).unwrap();
    let cfg = CanTactileConfig { interface: name.clone(), ..tactile_cfg() };
    let mut tactile = CanTactile::open(&cfg, Arc::new(WallClock::start())).unwrap();
    // The board's side: wait for the start command, then stream three scans.
    let start = board.recv(Duration::from_secs(1)).unwrap().expect("the start command");
    assert_eq!(start, cfg.legacy_layout().start_command());
    for s in 0..3 {
        for f in scan_frames(&cfg.legacy_layout(), s, None) {
            board.send(&f).unwrap();
        }
    }
    for s in 0..3u16 {
        assert_eq!(tactile.read().unwrap().raw[0], [s, 2, 5]);
    }
    let mut hand = CanHand::open(&CanHandConfig { interface: name, ..hand_cfg() }).unwrap();
    hand.command(&ActuatorCommand::FingerVolts([1.0; 3])).unwrap();
    let ids = hand_cfg().ids();
    let got = (0..50).find_map(|_| {
        let f = board.recv(Duration::from_millis(100)).ok()??;
        matches!(ids.decode(&f), Ok(Some(HandMessage::Setpoint { .. }))).then_some(f)
    });
    assert!(got.is_some(), "the set-point crossed the bus");
}

/// A bus that reports the given problems, then stays silent.
struct ProblemBus(Mutex<VecDeque<BusProblem>>);

impl CanBus for ProblemBus {
    fn send(&self, _: &CanFrame) -> io::Result<()> {
        Ok(())
    }
    fn recv(&self, _: Duration) -> io::Result<Option<CanFrame>> {
        Ok(None)
    }
    fn name(&self) -> &str {
        "err0"
    }
    fn recv_event(&self, timeout: Duration) -> io::Result<Option<BusEvent>> {
        if let Some(p) = self.0.lock().unwrap().pop_front() {
            return Ok(Some(BusEvent::Problem(p)));
        }
        std::thread::sleep(timeout.min(Duration::from_millis(2)));
        Ok(None)
    }
}

#[test]
fn bus_problems_are_named_and_bus_off_ends_the_source() {
    let problems = |p: &[BusProblem]| Arc::new(ProblemBus(Mutex::new(p.iter().copied().collect())));
    let clock = || Arc::new(WallClock::start());
    let bus = problems(&[BusProblem::NoAck, BusProblem::NoAck]);
    let mut tactile = CanTactile::with_bus(bus, &tactile_cfg(), 100.0, clock()).unwrap();
    let e = tactile.read().unwrap_err();
    assert_eq!(e.kind, ErrorKind::Timeout);
    assert!(
        e.detail.ends_with("last of 2 bus problems: no ACK: is another node on the bus at the same bitrate?"),
        "{e}"
    );

    let bus = problems(&[BusProblem::ErrorPassive, BusProblem::BusOff]);
    let mut tactile = CanTactile::with_bus(bus, &tactile_cfg(), 100.0, clock()).unwrap();
    let e = tactile.read().unwrap_err();
    assert_eq!(e.kind, ErrorKind::Disconnected);
    assert!(e.to_string().contains("err0") && e.detail.starts_with("bus-off"), "{e}");
    assert_eq!(tactile.read().unwrap_err().detail, e.detail, "it sticks");
}

#[test]
fn frames_are_stamped_with_their_age_on_the_session_clock() {
    struct AgedBus(Mutex<Option<CanFrame>>);
    impl CanBus for AgedBus {
        fn send(&self, _: &CanFrame) -> io::Result<()> {
            Ok(())
        }
        fn recv(&self, _: Duration) -> io::Result<Option<CanFrame>> {
            Ok(None)
        }
        fn name(&self) -> &str {
            "aged0"
        }
        fn recv_event(&self, _: Duration) -> io::Result<Option<BusEvent>> {
            Ok(self
                .0
                .lock()
                .unwrap()
                .take()
                .map(|frame| BusEvent::Frame { frame, age: Some(Duration::from_millis(30)) }))
        }
    }
    let mut cfg = tactile_cfg();
    cfg.sensors = vec![sensor("one", 0, 1, 1)];
    cfg.fingers = Some(PerFinger::from_fn(|_| FingerReading::taxel("one", 0)));
    let frame = cfg.legacy_layout().taxel_frame(0, [1, 2, 3], true);
    let clock = Arc::new(slidetrack_core::SimClock::new());
    clock.sleep_until(slidetrack_core::TimeNs(1_000_000_000));
    let mut tactile =
        CanTactile::with_bus(Arc::new(AgedBus(Mutex::new(Some(frame)))), &cfg, 100.0, clock).unwrap();
    let s = tactile.read().unwrap();
    assert_eq!(s.t, slidetrack_core::TimeNs(970_000_000), "received 30 ms before it was read");
}

#[test]
fn over_an_slcan_adapter_the_start_and_stop_frames_are_sent() {
    use crate::slcan::backend::SlcanBus;
    use crate::slcan::backend::emulator::{SlcanEmulator, SlcanEmulatorConfig};
    use crate::slcan::protocol::SlcanConfig;
    let mut cfg = tactile_cfg();
    cfg.start = Some(crate::can::layout::CommandFrame { id: 0x100, extended: false, data: vec![1] });
    cfg.stop = Some(crate::can::layout::CommandFrame { id: 0x100, extended: false, data: vec![0] });
    let layout = cfg.layout().unwrap();
    let n = layout.slots.len();
    let mut scan = 0u16;
    let source = Box::new(move || {
        scan += 1;
        Some(layout.encode_scan(&vec![[scan, 7, 9]; n]))
    });
    let emulator = SlcanEmulator::start(source, SlcanEmulatorConfig::default()).unwrap();
    let adapter = SlcanConfig { reply_timeout_ms: 2000, ..SlcanConfig::default() };
    let bus = Arc::new(SlcanBus::open(emulator.path(), &adapter).unwrap());
    cfg.startup_timeout_ms = 2000;
    let mut tactile = CanTactile::with_bus(bus, &cfg, 100.0, Arc::new(WallClock::start())).unwrap();
    let a = tactile.read().unwrap();
    let b = tactile.read().unwrap();
    assert_eq!(a.raw.len(), 14);
    assert!(b.raw[0][0] > a.raw[0][0] && a.raw.iter().all(|v| v[1..] == [7, 9]), "{a:?} {b:?}");
    drop(tactile);
    std::thread::sleep(Duration::from_millis(50));
    let sent: Vec<(u32, Vec<u8>)> =
        emulator.transmitted().iter().map(|f| (f.id, f.data().to_vec())).collect();
    assert_eq!(sent, [(0x100, vec![1]), (0x100, vec![0])], "start, then stop on drop");
    assert_eq!(emulator.record().commands.last().map(String::as_str), Some("C"), "the channel closed");
}
