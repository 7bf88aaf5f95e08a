//! The simulated parallel gripper: servo speed and force limits, position
//! steps, symmetric pads, the empty middle slot, the Robotiq status and the
//! release.

use std::sync::Arc;

use slidetrack_core::{
    ActuatorCommand, ActuatorSpec, GripperObject, GripperRequest, GripperSpec, HandActuator, HandMonitor,
    HandStatus, SimClock, SimTruth, TactileSource, TimeNs,
};
use slidetrack_sim::{HandKind, ObjectConfig, PatchConfig, SimDevices, SimRigConfig};

fn gripper_config() -> SimRigConfig {
    SimRigConfig { hand: HandKind::Gripper, ..SimRigConfig::default() }
}

/// A gripper trial of the box (50 mm wide: the pads touch it 105 steps closed).
fn rig(cfg: &SimRigConfig) -> SimDevices {
    let object = ObjectConfig::load("box").expect("the built-in box");
    SimDevices::new(cfg, &object, 4, 0, Arc::new(SimClock::new()))
}

/// Steps the world `secs` further.
fn run_for(sim: &SimDevices, secs: f64) {
    let mut world = sim.world.lock().expect("the world");
    let t = TimeNs(world.now().0 + (secs * 1e9).round() as u64);
    world.advance_to(t);
}

fn status(sim: &SimDevices) -> HandStatus {
    sim.hand_monitor().status().expect("a status").expect("a new status")
}

fn truth(sim: &SimDevices) -> SimTruth {
    sim.world.lock().expect("the world").truth()
}

fn request(sim: &mut SimDevices, position_steps: u16, speed: u8, force: u8) {
    let command = ActuatorCommand::Gripper(GripperRequest { position_steps, speed, force });
    sim.hand.command(&command).expect("a gripper request");
}

fn opening(sim: &SimDevices) -> f64 {
    status(sim).opening_m.expect("a gripper reports its opening")
}

fn object_detection(sim: &SimDevices) -> GripperObject {
    status(sim).gripper.expect("a gripper status").object
}

#[test]
fn the_opening_changes_at_the_requested_speed() {
    let spec = GripperSpec::robotiq_2f85();
    for speed in [0, 128, 255] {
        let mut sim = rig(&gripper_config());
        request(&mut sim, 100, speed, 0);
        run_for(&sim, 0.05);
        let (o0, t0) = (opening(&sim), 0.05);
        assert_eq!(object_detection(&sim), GripperObject::Moving);
        run_for(&sim, 0.1);
        let rate = (o0 - opening(&sim)) / (0.15 - t0);
        let expected = spec.speed_mps(speed);
        assert!((rate - expected).abs() < 0.01 * expected, "speed {speed}: {rate} m/s, expected {expected}");
    }
}

#[test]
fn the_grip_force_never_exceeds_the_requested_force_and_the_current_follows_it() {
    let spec = GripperSpec::robotiq_2f85();
    for force in [0, 20] {
        let mut sim = rig(&gripper_config());
        request(&mut sim, 255, 255, force);
        let limit = spec.force_n(force);
        for _ in 0..1000 {
            run_for(&sim, 0.002);
            let n = truth(&sim).normal_n;
            assert!(n[0] <= limit * (1.0 + 1e-9) && n[1] <= limit * (1.0 + 1e-9), "{n:?} above {limit} N");
        }
        let n = truth(&sim).normal_n;
        let grip = (n[0] + n[1]) / 2.0;
        assert!((grip - limit).abs() < 1e-3 * limit, "force {force}: grip {grip} N, limit {limit} N");
        let g = status(&sim).gripper.expect("a gripper status");
        assert_eq!(g.object, GripperObject::ContactClosing);
        assert_eq!(g.current_ma, (4.0 * limit).round() as u32, "4 mA per newton of servo force");
    }
}

#[test]
fn only_whole_steps_are_requested_and_positions_are_clamped() {
    let spec = GripperSpec::robotiq_2f85();
    let mut sim = rig(&gripper_config());
    for steps in [37, 80, 3] {
        request(&mut sim, steps, 255, 0);
        run_for(&sim, 0.5);
        let s = status(&sim);
        let expected = spec.stroke_m - f64::from(steps) * spec.step_m();
        assert!((s.opening_m.expect("opening") - expected).abs() < 1e-9, "{steps} steps: {s:?}");
        let g = s.gripper.expect("a gripper status");
        assert_eq!((g.position_steps, g.requested_steps), (steps, steps));
        assert_eq!(g.object, GripperObject::AtRequest);
    }
    request(&mut sim, 900, 255, 0);
    assert_eq!(status(&sim).gripper.expect("a gripper status").requested_steps, 255);
}

#[test]
fn both_pads_close_symmetrically_and_press_alike() {
    let mut sim = rig(&gripper_config());
    request(&mut sim, 90, 100, 0);
    for _ in 0..20 {
        run_for(&sim, 0.01);
        let s = status(&sim);
        let closure = GripperSpec::robotiq_2f85().stroke_m - s.opening_m.expect("opening");
        assert_eq!(s.finger_travel_m.len(), 2, "two pads");
        assert_eq!(s.finger_travel_m[0], s.finger_travel_m[1]);
        assert!((s.finger_travel_m[0] - closure / 2.0).abs() < 1e-12, "{s:?}");
    }
    request(&mut sim, 115, 100, 0);
    run_for(&sim, 1.0);
    let n = truth(&sim).normal_n;
    assert!(n[0] > 0.5 && n[0] == n[1], "{n:?}");
}

#[test]
fn the_middle_slot_carries_nothing() {
    for patch in [None, Some(PatchConfig { rows: 4, cols: 4, pitch_mm: 4.7, contact_sigma_mm: 5.0 })] {
        let mut cfg = gripper_config();
        cfg.tactile.patch = patch;
        let mut sim = rig(&cfg);
        let info = sim.tactile.info();
        let names: Vec<_> =
            info.layout.sensors.iter().map(|s| (s.name.as_str(), s.finger.as_str())).collect();
        assert_eq!(names, [("left", "thumb"), ("right", "index")]);
        let fingers = info.finger_map().expect("the gripper layout resolves");
        // Grip, lift, then loosen until the box slides and falls.
        request(&mut sim, 115, 255, 0);
        for (k, steps) in (0..300).map(|k| (k, if k < 150 { 115 } else { 108 })) {
            request(&mut sim, steps, 255, 0);
            let scan = sim.tactile.read().expect("a scan");
            assert_eq!(scan.raw.len(), 2 * info.layout.sensors[0].taxels(), "scan {k}");
            let t = truth(&sim);
            assert_eq!((t.normal_n[2], t.friction_n[2]), (0.0, 0.0), "scan {k}: {t:?}");
            let counts: Vec<[f64; 3]> = scan.raw.iter().map(|r| r.map(f64::from)).collect();
            let readings = fingers.read(&counts);
            assert_eq!(readings.middle, readings.index, "the middle reading repeats the right pad's");
        }
        assert!(!truth(&sim).supported, "the arm lifted the box");
    }
}

#[test]
fn object_detection_follows_the_grasp() {
    let mut sim = rig(&gripper_config());
    assert_eq!(object_detection(&sim), GripperObject::AtRequest, "open, at the open request");
    request(&mut sim, 200, 255, 0);
    run_for(&sim, 0.1);
    assert_eq!(object_detection(&sim), GripperObject::Moving);
    run_for(&sim, 0.5);
    assert_eq!(
        object_detection(&sim),
        GripperObject::ContactClosing,
        "stopped on the box by the force limit"
    );
    request(&mut sim, 115, 255, 0);
    run_for(&sim, 1.0);
    assert_eq!(object_detection(&sim), GripperObject::ContactClosing, "holding the box short of the request");
    assert!(!truth(&sim).supported, "the arm lifted the box");
    request(&mut sim, 100, 255, 0);
    run_for(&sim, 1.0);
    assert!(truth(&sim).dropped, "the box fell");
    assert_eq!(object_detection(&sim), GripperObject::AtRequest, "at the request, the object lost");
    sim.hand.release().expect("a release");
    run_for(&sim, 0.05);
    assert_eq!(object_detection(&sim), GripperObject::Moving);
}

#[test]
fn a_release_opens_fully_at_full_speed() {
    let spec = GripperSpec::robotiq_2f85();
    let mut sim = rig(&gripper_config());
    request(&mut sim, 200, 255, 0);
    run_for(&sim, 1.0);
    sim.hand.release().expect("a release");
    // Off the object (unloading the pads slows the first 0.13 s a little), then
    // at full speed.
    run_for(&sim, 0.2);
    let o0 = opening(&sim);
    run_for(&sim, 0.1);
    let rate = (opening(&sim) - o0) / 0.1;
    assert!((rate - spec.speed_range_mps.1).abs() < 1e-3, "opening at {rate} m/s");
    run_for(&sim, 1.0);
    let s = status(&sim);
    assert!((s.opening_m.expect("opening") - spec.stroke_m).abs() < 1e-9);
    let g = s.gripper.expect("a gripper status");
    assert_eq!((g.position_steps, g.requested_steps, g.object), (0, 0, GripperObject::AtRequest));
}

#[test]
fn the_gripper_takes_gripper_requests_only() {
    let mut sim = rig(&gripper_config());
    assert_eq!(sim.hand.spec(), ActuatorSpec::Gripper(GripperSpec::robotiq_2f85()));
    let e = sim.hand.command(&ActuatorCommand::FingerVolts([1.0; 3])).expect_err("volts refused");
    assert!(e.to_string().contains("accepts gripper requests only"), "{e}");
    let (mut gripper, _monitor) = sim.gripper_pair().expect("a gripper for an emulator");
    gripper
        .command(&ActuatorCommand::Gripper(GripperRequest { position_steps: 50, speed: 255, force: 0 }))
        .expect("a request");
    run_for(&sim, 0.5);
    assert_eq!(gripper.status().expect("a status").0.position_steps, 50);
    let three = rig(&SimRigConfig::default());
    assert!(three.gripper_pair().is_none());
    assert!(status(&three).gripper.is_none());
}

#[test]
fn bad_gripper_values_name_the_field() {
    let mut cfg = gripper_config();
    cfg.gripper.stroke_m = -0.085;
    let e = cfg.validate().expect_err("a negative stroke").to_string();
    assert!(e.starts_with("sim.gripper.stroke_m: must be a positive number"), "{e}");
    let mut cfg = gripper_config();
    cfg.gripper.force_range_n = [235.0, 20.0];
    let e = cfg.validate().expect_err("a reversed range").to_string();
    assert!(e.starts_with("sim.gripper.force_range_n:"), "{e}");
    let mut cfg = gripper_config();
    cfg.gripper.stroke_m = 0.04;
    let object = ObjectConfig::load("box").expect("the built-in box");
    let e = cfg.check_object(&object).expect_err("too narrow").to_string();
    assert!(e.contains("less than the width of object 'box'"), "{e}");
    let e = toml::from_str::<SimRigConfig>("hand = \"claw\"\n").expect_err("an unknown hand").to_string();
    assert!(e.contains("three_finger") && e.contains("gripper"), "{e}");
}
