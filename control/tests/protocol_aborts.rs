//! The protocol's safety limits, driven scan by scan without a rig.

use slidetrack_control::{AbortReason, GraspProfile, HandAction, Protocol, ProtocolConfig, ProtocolSettings};
use slidetrack_core::{ActuatorCommand, DeviceError, ErrorKind, Phase, TactileInfo, TactileSample, TimeNs};

const BASE: u16 = 30_000;

fn protocol() -> Protocol {
    Protocol::new(
        ProtocolConfig {
            settings: ProtocolSettings::default(),
            profile: GraspProfile { max_counts: 2000.0, min_counts: 800.0, period_s: 10.0, sharpness: 1.0 },
            travel_limit_m: 0.1,
            cycles_duration_s: 5.0,
        },
        TactileInfo::one_module_per_finger("test", 100.0, "test")
            .finger_map()
            .expect("the thesis hand resolves"),
    )
}

fn scan(k: u64, z_counts: u16) -> TactileSample {
    TactileSample::new(TimeNs(k * 10_000_000), k, vec![[BASE, BASE, z_counts]; 3])
}

/// Feeds open-hand scans until the protocol leaves the zero phase; returns the next scan index.
fn zeroed(p: &mut Protocol) -> u64 {
    let mut k = 1;
    while p.phase() == Phase::Zero {
        p.on_tactile(&scan(k, BASE));
        k += 1;
    }
    k
}

#[test]
fn baseline_is_the_mean_of_the_open_hand_scans() {
    let mut p = protocol();
    let mut tare = None;
    for k in 1..100 {
        let out = p.on_tactile(&scan(k, BASE + (k % 2) as u16 * 10));
        if out.tare.is_some() {
            tare = out.tare;
            break;
        }
    }
    let tare = tare.expect("a tare after the zero phase");
    assert!((tare.baseline[0][2] - (f64::from(BASE) + 5.0)).abs() < 0.2, "{tare:?}");
    // 0.5 s of scans at 100 Hz, both ends included.
    assert_eq!(tare.scans, 51);
    assert_eq!(p.phase(), Phase::Close);
}

#[test]
fn a_single_spike_does_not_abort_but_saturation_does() {
    let mut p = protocol();
    let k = zeroed(&mut p);
    p.on_tactile(&scan(k, u16::MAX));
    p.on_tactile(&scan(k + 1, BASE));
    assert_eq!(p.phase(), Phase::Close, "a one-scan spike is neither a touch nor a saturation");
    let mut last = None;
    for j in 0..3 {
        last = Some(p.on_tactile(&scan(k + 2 + j, u16::MAX)));
    }
    assert_eq!(p.phase(), Phase::Aborted);
    let out = last.unwrap();
    assert_eq!(out.action, Some(HandAction::Release));
    match p.abort_reason() {
        Some(AbortReason::Saturated { axis: "z", counts: u16::MAX, scans: 3, .. }) => {}
        other => panic!("{other:?}"),
    }
    assert!(out.events[0].message.contains("saturated"), "{}", out.events[0].message);
}

#[test]
fn no_contact_before_the_timeout_aborts_and_names_the_fingers() {
    let mut p = protocol();
    let mut k = zeroed(&mut p);
    let mut closing = false;
    while !p.finished() && k < 10_000 {
        let out = p.on_tactile(&scan(k, BASE));
        closing |=
            matches!(out.action, Some(HandAction::Command(ActuatorCommand::FingerVolts(v))) if v[0] > 0.0);
        k += 1;
    }
    assert!(closing, "the fingers were told to close");
    let msg = p.abort_reason().unwrap().to_string();
    assert!(msg.contains("thumb") && msg.contains("index") && msg.contains("middle"), "{msg}");
}

#[test]
fn marker_beyond_the_travel_limit_aborts_and_a_missing_marker_does_not() {
    let mut p = protocol();
    zeroed(&mut p);
    assert!(p.on_marker(None).is_none());
    assert!(p.on_marker(Some(0.05)).is_none());
    let event = p.on_marker(Some(0.12)).unwrap();
    assert!(event.message.contains("12.0 cm"), "{}", event.message);
    assert!(p.on_marker(Some(0.2)).is_none(), "abort happens once");
}

#[test]
fn stale_data_and_device_errors_abort() {
    let mut p = protocol();
    assert!(p.check_data_age(TimeNs(40_000_000), TimeNs(0)).is_none());
    let e = p.check_data_age(TimeNs(60_000_000), TimeNs(0)).unwrap();
    assert!(e.message.contains("60 ms"), "{}", e.message);

    let mut p = protocol();
    let e = p.device_error(DeviceError::new(ErrorKind::Disconnected, "/dev/ttyACM0", "read failed")).unwrap();
    assert!(e.message.contains("/dev/ttyACM0"), "{}", e.message);
    assert!(p.finished());
}
