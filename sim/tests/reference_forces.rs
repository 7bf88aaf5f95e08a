//! The reference force per taxel (`SimWorld::taxel_forces_n`): a patch's
//! taxels share the contact force, in each module's frame; asking for it
//! changes no counts.

use std::sync::Arc;

use nalgebra::{Rotation3, Vector3};
use slidetrack_core::{SimClock, TactileSource, TimeNs};
use slidetrack_sim::{ObjectConfig, PatchConfig, SimDevices, SimRigConfig, SimWorld};

fn patch_rig() -> SimRigConfig {
    let mut cfg = SimRigConfig::default();
    cfg.tactile.patch = Some(PatchConfig { rows: 4, cols: 4, pitch_mm: 4.7, contact_sigma_mm: 5.0 });
    cfg
}

/// Holds the box at 2 V on the thumb (1 V on the others) for 1.5 s.
fn grasp(world: &mut SimWorld) {
    world.set_volts([2.0, 1.0, 1.0]);
    world.advance_to(TimeNs(1_500_000_000));
}

#[test]
fn the_taxels_of_a_patch_share_the_contact_force_in_their_modules_frames() {
    let cfg = patch_rig();
    let object = ObjectConfig::load("box").unwrap();
    let mut world = SimWorld::new(&cfg, &object, 3, 0);
    grasp(&mut world);
    let truth = world.truth();
    let forces = world.taxel_forces_n();
    assert_eq!(forces.len(), 3 * 16);
    for f in 0..3 {
        let [r, p, y] = cfg.tactile.mount_rpy_deg[f].map(f64::to_radians);
        let module_from_contact = Rotation3::from_euler_angles(r, p, y);
        let sum: Vector3<f64> = forces[16 * f..16 * (f + 1)].iter().map(|v| Vector3::from(*v)).sum();
        let in_contact = module_from_contact.inverse() * sum;
        assert!(truth.normal_n[f] > 0.3, "finger {f} holds the box: {truth:?}");
        assert!((in_contact.z - truth.normal_n[f]).abs() < 1e-9, "finger {f}: {in_contact} vs {truth:?}");
        assert!(in_contact.y.abs() < 1e-9, "no lateral force: {in_contact}");
        // The taxel under the contact's centre feels more than a corner one.
        assert!(forces[16 * f + 5][2].abs() > forces[16 * f][2].abs());
    }
}

#[test]
fn asking_for_reference_forces_changes_no_count() {
    let object = ObjectConfig::load("box").unwrap();
    let scans = |reference_forces: bool| {
        let cfg = SimRigConfig { reference_forces, ..SimRigConfig::default() };
        let mut sim = SimDevices::new(&cfg, &object, 5, 1, Arc::new(SimClock::new()));
        sim.world.lock().unwrap().set_volts([2.0, 1.0, 1.0]);
        (0..150).map(|_| sim.tactile.read().unwrap()).collect::<Vec<_>>()
    };
    let (with, without) = (scans(true), scans(false));
    assert!(without.iter().all(|s| s.reference_n.is_none()));
    assert!(with.iter().all(|s| s.reference_n.as_ref().is_some_and(|r| r.len() == 3)));
    let raw = |v: &[slidetrack_core::TactileSample]| v.iter().map(|s| s.raw.clone()).collect::<Vec<_>>();
    assert_eq!(raw(&with), raw(&without));
    assert!(with.last().unwrap().reference_n.as_ref().unwrap()[0][2] > 0.3, "the thumb presses by then");
}
