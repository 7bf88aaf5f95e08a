//! The grasp controller's spike gate, driven scan by scan without a rig.

use slidetrack_control::{
    GraspProfile, HandAction, Protocol, ProtocolConfig, ProtocolSettings, ZSpikeGateConfig,
};
use slidetrack_core::{ActuatorCommand, Phase, TactileInfo, TactileSample, TimeNs};

const BASE: u16 = 30_000;

fn protocol(gate: ZSpikeGateConfig) -> Protocol {
    Protocol::new(
        ProtocolConfig {
            settings: ProtocolSettings { z_spike_gate: gate, ..ProtocolSettings::default() },
            profile: GraspProfile { max_counts: 2000.0, min_counts: 800.0, period_s: 10.0, sharpness: 1.0 },
            travel_limit_m: 0.1,
            cycles_duration_s: 5.0,
        },
        TactileInfo::one_module_per_finger("test", 100.0, "test")
            .finger_map()
            .expect("the thesis hand resolves"),
    )
}

/// The thumb's command (V) for each scan of a grasp held at 500 counts, with
/// `spike` counts added to the thumb's z at one scan of the settling phase.
fn thumb_volts(gate: ZSpikeGateConfig, spike: u16) -> Vec<f64> {
    let mut p = protocol(gate);
    let mut volts = Vec::new();
    let mut spiked = false;
    for k in 1..600u64 {
        let open = p.phase() == Phase::Zero;
        let mut z = [if open { BASE } else { BASE + 500 }; 3];
        if p.phase() == Phase::Settle && !spiked {
            z[0] += spike;
            spiked = true;
        }
        let raw = z.iter().map(|&z| [BASE, BASE, z]).collect();
        let out = p.on_tactile(&TactileSample::new(TimeNs(k * 10_000_000), k, raw));
        if let Some(HandAction::Command(ActuatorCommand::FingerVolts(v))) = out.action {
            volts.push(v[0]);
        }
    }
    assert!(spiked, "the trial never settled: {:?}", p.phase());
    volts
}

/// Catches a gate that is not in the loop: an isolated 2000-count spike on
/// the thumb changes the thumb's command without it and not at all with it.
#[test]
fn an_isolated_spike_does_not_move_the_grasp() {
    let quiet = thumb_volts(ZSpikeGateConfig::default(), 0);
    let gated = thumb_volts(ZSpikeGateConfig::default(), 2000);
    assert_eq!(quiet.len(), gated.len());
    assert_eq!(quiet, gated);
    let off = ZSpikeGateConfig { max_step_counts: 0.0, ..ZSpikeGateConfig::default() };
    let ungated = thumb_volts(off, 2000);
    let largest = quiet.iter().zip(&ungated).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
    assert!(largest > 0.1, "without the gate the spike moves the thumb by {largest} V");
}
