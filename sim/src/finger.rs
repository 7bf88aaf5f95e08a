//! A finger of the simulated hand: a voltage-driven first-order actuator, an
//! overdamped proximal joint and a soft fingertip with a nonlinear contact law.

use serde::{Deserialize, Serialize};

/// Parameters of one finger, its actuator and its fingertip pad.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct FingerConfig {
    /// Steady-state closing force per volt of the proximal joint (N/V).
    pub actuator_gain_n_per_v: f64,
    /// Time constant of the actuator (s).
    pub actuator_time_constant_s: f64,
    /// Viscous resistance of the finger to moving (N s/m).
    pub damping_n_s_per_m: f64,
    /// Distance between the open fingertip and the object's surface (m).
    pub gap_m: f64,
    /// Hertz-like contact law of the soft pad, `F = k delta^1.5` (N/m^1.5).
    pub contact_stiffness_n_per_m15: f64,
    /// Tangential stiffness of the pad: shear displacement = friction / stiffness (N/m).
    pub pad_shear_stiffness_n_per_m: f64,
    /// How far the fingertip can open behind its rest position (m).
    pub open_limit_m: f64,
    /// How far the fingertip can close beyond its rest position (m).
    pub close_limit_m: f64,
}

impl Default for FingerConfig {
    fn default() -> Self {
        FingerConfig {
            actuator_gain_n_per_v: 0.5,
            actuator_time_constant_s: 0.02,
            damping_n_s_per_m: 20.0,
            gap_m: 0.004,
            // 1 N indents the pad by 0.5 mm.
            contact_stiffness_n_per_m15: 1.0 / (0.0005f64).powf(1.5),
            pad_shear_stiffness_n_per_m: 1500.0,
            open_limit_m: 0.02,
            close_limit_m: 0.03,
        }
    }
}

/// The state of one finger.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FingerState {
    /// Force the actuator develops (N), lagging `gain * volts`.
    pub actuation_n: f64,
    /// Fingertip travel from its open rest position towards the object (m).
    pub position_m: f64,
    /// Pad indentation into the object (m), 0 without contact.
    pub indentation_m: f64,
    /// Contact normal force (N).
    pub normal_n: f64,
}

impl FingerConfig {
    /// Contact force (N) and stiffness (N/m) at indentation `delta_m`.
    pub fn contact(&self, delta_m: f64) -> (f64, f64) {
        if delta_m <= 0.0 {
            return (0.0, 0.0);
        }
        let s = delta_m.sqrt();
        let k = self.contact_stiffness_n_per_m15;
        (k * delta_m * s, 1.5 * k * s)
    }

    /// Indentation (m) that produces the normal force `force_n` (inverse of [`Self::contact`]).
    pub fn indentation_for(&self, force_n: f64) -> f64 {
        (force_n.max(0.0) / self.contact_stiffness_n_per_m15).powf(2.0 / 3.0)
    }
}

impl FingerState {
    /// Advances the finger over `dt_s` under `volts`. `surface_m` is how far
    /// the object's surface under the fingertip stands out from its nominal
    /// plane (texture); `in_contact` is false when there is no object.
    ///
    /// Actuator: `tau du/dt = k_v V - u`, integrated exactly for a constant `V`.
    /// Finger: `b dx/dt = u - F_n(x - gap + surface)`, one linearly-implicit
    /// step so that the stiff contact stays stable.
    pub fn step(&mut self, cfg: &FingerConfig, volts: f64, surface_m: f64, in_contact: bool, dt_s: f64) {
        let alpha = 1.0 - (-dt_s / cfg.actuator_time_constant_s).exp();
        self.actuation_n += alpha * (cfg.actuator_gain_n_per_v * volts - self.actuation_n);
        let offset = surface_m - cfg.gap_m;
        let delta = if in_contact { self.position_m + offset } else { 0.0 };
        let (force, stiffness) = cfg.contact(delta);
        let dx = dt_s * (self.actuation_n - force) / (cfg.damping_n_s_per_m + dt_s * stiffness);
        self.position_m = (self.position_m + dx).clamp(-cfg.open_limit_m, cfg.close_limit_m);
        self.indentation_m = if in_contact { (self.position_m + offset).max(0.0) } else { 0.0 };
        self.normal_n = cfg.contact(self.indentation_m).0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn steady_contact_force_equals_actuator_force() {
        let cfg = FingerConfig::default();
        let mut f = FingerState::default();
        for _ in 0..4000 {
            f.step(&cfg, 2.0, 0.0, true, 5e-4);
        }
        assert!((f.normal_n - 1.0).abs() < 1e-6, "{}", f.normal_n);
        assert!((f.indentation_m - 0.0005).abs() < 1e-8);
    }

    #[test]
    fn free_finger_closes_at_force_over_damping() {
        let cfg = FingerConfig::default();
        let mut f = FingerState { actuation_n: 1.0, ..FingerState::default() };
        f.step(&cfg, 2.0, 0.0, false, 1e-3);
        assert!((f.position_m - 1.0 / cfg.damping_n_s_per_m * 1e-3).abs() < 1e-9);
    }

    #[test]
    fn indentation_inverts_the_contact_law() {
        let cfg = FingerConfig::default();
        let d = cfg.indentation_for(0.7);
        assert!((cfg.contact(d).0 - 0.7).abs() < 1e-12);
    }
}
