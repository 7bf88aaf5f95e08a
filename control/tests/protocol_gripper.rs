//! The protocol on a position-controlled gripper, driven scan by scan
//! without a rig: the pads are the thumb and index readings, the middle
//! reading is not used, and the PI law moves the position request.

use slidetrack_control::{AbortReason, GraspProfile, HandAction, Protocol, ProtocolConfig, ProtocolSettings};
use slidetrack_core::{
    ActuatorCommand, ActuatorSpec, Finger, GripperSpec, Phase, TactileInfo, TactileSample, TimeNs,
};

const BASE: u16 = 30_000;

fn gripper_protocol() -> Protocol {
    let mut settings = ProtocolSettings::default();
    settings.gripper.approach_steps = 100;
    settings.gripper.close_rate_steps_per_s = 50.0;
    Protocol::for_actuator(
        ProtocolConfig {
            settings,
            profile: GraspProfile { max_counts: 2000.0, min_counts: 800.0, period_s: 10.0, sharpness: 1.0 },
            travel_limit_m: 0.1,
            cycles_duration_s: 5.0,
        },
        TactileInfo::one_module_per_finger("test", 100.0, "test")
            .finger_map()
            .expect("the thesis hand resolves"),
        &ActuatorSpec::Gripper(GripperSpec::robotiq_2f85()),
    )
}

/// Scan `k` with z (counts above the baseline) per finger.
fn scan(k: u64, dz: [u16; 3]) -> TactileSample {
    TactileSample::new(TimeNs(k * 10_000_000), k, dz.iter().map(|d| [BASE, BASE, BASE + d]).collect())
}

fn request(action: Option<HandAction>) -> u16 {
    match action {
        Some(HandAction::Command(ActuatorCommand::Gripper(r))) => r.position_steps,
        other => panic!("expected a gripper request, got {other:?}"),
    }
}

/// Feeds open scans through the zero phase; returns the next scan index.
fn zeroed(p: &mut Protocol) -> u64 {
    let first = p.on_tactile(&scan(1, [0; 3]));
    assert_eq!(request(first.action), 100, "the gripper waits at the approach position");
    let mut k = 2;
    while p.phase() == Phase::Zero {
        p.on_tactile(&scan(k, [0; 3]));
        k += 1;
    }
    k
}

#[test]
fn closes_on_both_pads_and_ignores_the_middle_reading() {
    let mut p = gripper_protocol();
    let mut k = zeroed(&mut p);
    let mut last = 0;
    for _ in 0..20 {
        last = request(p.on_tactile(&scan(k, [0; 3])).action);
        k += 1;
    }
    // 20 ticks of 10 ms at 50 steps/s close the request by 10 steps.
    assert!((109..=111).contains(&last), "{last}");
    // Both pads touch; the middle reading (no finger on a gripper) stays 0.
    p.on_tactile(&scan(k, [100, 100, 0]));
    p.on_tactile(&scan(k + 1, [100, 100, 0]));
    assert_eq!(p.phase(), Phase::Ramp, "thumb and index pads are the whole grasp");
}

#[test]
fn more_grasp_error_means_a_deeper_request() {
    let mut p = gripper_protocol();
    let mut k = zeroed(&mut p);
    p.on_tactile(&scan(k, [100, 100, 0]));
    let contact = request(p.on_tactile(&scan(k + 1, [100, 100, 0])).action);
    k += 2;
    // Pads far below the reference: the request closes beyond contact.
    let mut deepest = contact;
    for _ in 0..150 {
        deepest = request(p.on_tactile(&scan(k, [130, 130, 0])).action);
        k += 1;
    }
    assert!(deepest > contact + 5, "contact {contact}, after 1.5 s of error {deepest}");
    // Saturation: never more than 40 steps beyond contact (the default).
    for _ in 0..500 {
        deepest = request(p.on_tactile(&scan(k, [130, 130, 0])).action);
        k += 1;
    }
    assert_eq!(deepest, contact + 40);
}

#[test]
fn no_contact_names_only_the_pads() {
    let mut p = gripper_protocol();
    let mut k = zeroed(&mut p);
    let mut abort = None;
    while abort.is_none() && k < 2000 {
        let out = p.on_tactile(&scan(k, [100, 0, 0]));
        abort = out.events.into_iter().find_map(|e| e.abort);
        k += 1;
    }
    match abort {
        Some(AbortReason::NoContact { fingers, .. }) => assert_eq!(fingers, vec![Finger::Index]),
        other => panic!("expected no contact on the index pad, got {other:?}"),
    }
}
