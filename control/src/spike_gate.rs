//! A gate on the grasp controller's z readings against isolated tactile
//! spikes. A 3-axis taxel now and then reports one wild sample (the
//! simulated sensor: 400-2500 counts, as real ones do); fed to the PI loop,
//! a spike becomes a real grasp-force transient that the object feels, and a
//! negative one can end a trial as "contact lost". The gate holds a finger's
//! last accepted reading while a new one departs from it by more than
//! `max_step_counts`, for at most `max_held_ticks` ticks in a row; after
//! that the reading is taken as it is (a real step, such as an object
//! knocked in the hand, is followed with that delay).

use serde::{Deserialize, Serialize};

/// Settings of [`ZSpikeGate`] (the `[protocol.z_spike_gate]` table of a rig TOML).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ZSpikeGateConfig {
    /// Largest change of a finger's baseline-subtracted z from one control
    /// tick to the next that is taken as real (counts); 0 turns the gate off.
    /// The default is twice the largest change measured between 100 Hz
    /// ticks of simulated grasps (about 300 counts, at the end of the ramp).
    pub max_step_counts: f64,
    /// Longest run of ticks a finger's reading is held (ticks).
    pub max_held_ticks: u32,
}

impl Default for ZSpikeGateConfig {
    fn default() -> Self {
        ZSpikeGateConfig { max_step_counts: 600.0, max_held_ticks: 2 }
    }
}

/// The gate of the three fingers' z readings (counts).
#[derive(Clone, Debug)]
pub struct ZSpikeGate {
    cfg: ZSpikeGateConfig,
    last: [Option<f64>; 3],
    held: [u32; 3],
    held_total: u64,
}

impl ZSpikeGate {
    /// A gate with nothing accepted yet.
    pub fn new(cfg: ZSpikeGateConfig) -> ZSpikeGate {
        ZSpikeGate { cfg, last: [None; 3], held: [0; 3], held_total: 0 }
    }

    /// Forgets the accepted readings (the next ones are taken as they are).
    pub fn reset(&mut self) {
        self.last = [None; 3];
        self.held = [0; 3];
    }

    /// Readings held so far, over every finger.
    pub fn held_total(&self) -> u64 {
        self.held_total
    }

    /// The readings the controller uses for this tick's `z` (counts).
    pub fn filter(&mut self, z: [f64; 3]) -> [f64; 3] {
        let on = self.cfg.max_step_counts > 0.0;
        [0, 1, 2].map(|f| match self.last[f] {
            Some(last)
                if on
                    && (z[f] - last).abs() > self.cfg.max_step_counts
                    && self.held[f] < self.cfg.max_held_ticks =>
            {
                self.held[f] += 1;
                self.held_total += 1;
                last
            }
            _ => {
                self.held[f] = 0;
                self.last[f] = Some(z[f]);
                z[f]
            }
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(gate: &mut ZSpikeGate, thumb: &[f64]) -> Vec<f64> {
        thumb.iter().map(|&z| gate.filter([z, 100.0, 100.0])[0]).collect()
    }

    /// Catches a gate that is off, or that holds for ever (a real step never
    /// followed), or that lets the first sample after a spike through.
    #[test]
    fn an_isolated_spike_is_held_and_a_real_step_followed_after_two_ticks() {
        let mut gate = ZSpikeGate::new(ZSpikeGateConfig::default());
        let out = run(&mut gate, &[500.0, 510.0, 2900.0, 520.0, 530.0]);
        assert_eq!(out, [500.0, 510.0, 510.0, 520.0, 530.0]);
        let out = run(&mut gate, &[-900.0, -900.0, -900.0, -900.0]);
        assert_eq!(out, [530.0, 530.0, -900.0, -900.0]);
        assert_eq!(gate.held_total(), 3);
    }

    /// Changes up to the limit pass untouched; the other fingers are their own.
    #[test]
    fn ordinary_changes_pass_and_fingers_are_gated_apart() {
        let mut gate = ZSpikeGate::new(ZSpikeGateConfig::default());
        let zs = [[0.0, 0.0, 0.0], [590.0, 3000.0, -10.0], [1100.0, 20.0, 580.0]];
        let out: Vec<[f64; 3]> = zs.iter().map(|&z| gate.filter(z)).collect();
        assert_eq!(out, [[0.0, 0.0, 0.0], [590.0, 0.0, -10.0], [1100.0, 20.0, 580.0]]);
    }

    #[test]
    fn zero_turns_it_off_and_reset_forgets() {
        let mut gate = ZSpikeGate::new(ZSpikeGateConfig { max_step_counts: 0.0, max_held_ticks: 2 });
        assert_eq!(run(&mut gate, &[0.0, 5000.0, 0.0]), [0.0, 5000.0, 0.0]);
        let mut gate = ZSpikeGate::new(ZSpikeGateConfig::default());
        run(&mut gate, &[0.0]);
        gate.reset();
        assert_eq!(run(&mut gate, &[5000.0]), [5000.0]);
    }
}
