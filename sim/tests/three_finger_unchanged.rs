//! The default three-finger rig gives the same data for the same seed as
//! before the gripper configuration existed: checksums of short runs'
//! tactile scans and truth, recorded from the code at 791a9ef.
//!
//! The checksums cover the exact bits of every `f64` of the truth, so they
//! hold for one platform's libm (x86-64 Linux, where they were recorded).

use slidetrack_core::TimeNs;
use slidetrack_sim::{ObjectConfig, PatchConfig, SimRigConfig, SimWorld};

/// FNV-1a over 64-bit words.
struct Fnv(u64);

impl Fnv {
    fn new() -> Fnv {
        Fnv(0xcbf2_9ce4_8422_2325)
    }
    fn word(&mut self, w: u64) {
        for b in w.to_le_bytes() {
            self.0 ^= u64::from(b);
            self.0 = self.0.wrapping_mul(0x0100_0000_01b3);
        }
    }
}

/// Closes the hand at `hold_volts` (thumb; half on index and middle), lets
/// the arm lift, then lowers the voltages so that the object slides, for 4 s; checksums (tactile scans, truth) at 100 Hz.
fn run(cfg: &SimRigConfig, object: &str, hold_volts: f64, seed: u64, trial: u32) -> (u64, u64, usize) {
    let object = ObjectConfig::load(object).expect("a built-in object");
    let mut world = SimWorld::new(cfg, &object, seed, trial);
    let (mut scans, mut truth) = (Fnv::new(), Fnv::new());
    let mut count = 0;
    for k in 1..=400u64 {
        let t_s = k as f64 * 0.01;
        let volts = if t_s < 2.0 { hold_volts } else { hold_volts * (1.0 - 0.35 * (t_s - 2.0)) };
        world.set_volts([volts, volts / 2.0, volts / 2.0]);
        world.advance_to(TimeNs(k * 10_000_000));
        for taxel in world.scan_tactile() {
            count += 1;
            for c in taxel {
                scans.word(u64::from(c));
            }
        }
        let t = world.truth();
        truth.word(t.t.0);
        for v in [t.position_m, t.velocity_mps].iter().chain(&t.normal_n).chain(&t.friction_n) {
            truth.word(v.to_bits());
        }
        truth.word(u64::from(t.supported) | u64::from(t.dropped) << 1);
    }
    (scans.0, truth.0, count)
}

#[test]
fn the_default_rig_gives_the_recorded_data() {
    let got = run(&SimRigConfig::default(), "box", 3.0, 7, 1);
    assert_eq!(got, (0x9ac15a6766e35cb4, 0x449fe7f7b876eceb, 1200));
}

#[test]
fn the_default_rig_with_patches_gives_the_recorded_data() {
    let mut cfg = SimRigConfig::default();
    cfg.tactile.patch = Some(PatchConfig { rows: 4, cols: 4, pitch_mm: 4.7, contact_sigma_mm: 5.0 });
    let got = run(&cfg, "mustard", 8.0, 3, 2);
    assert_eq!(got, (0x3e125585785bd2ef, 0x5d5e5a3be6fb03f0, 19200));
}
