//! The PI law (6.9) of one finger, with voltage saturation, a rate limit and
//! back-calculation anti-windup.

use serde::{Deserialize, Serialize};

/// Gains and limits of one finger's PI controller.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PiConfig {
    /// Proportional gain `k_p` (V per count of z error).
    pub kp_volt_per_count: f64,
    /// Integral gain `k_i` (V per count-second).
    pub ki_volt_per_count_s: f64,
    /// Output saturation (V).
    pub max_volts: f64,
    /// Largest change of the output per second (V/s).
    pub rate_limit_volt_per_s: f64,
    /// Anti-windup tracking time constant (s): how fast the integral follows
    /// the saturated output.
    pub tracking_time_s: f64,
}

impl Default for PiConfig {
    fn default() -> Self {
        PiConfig {
            kp_volt_per_count: 6e-4,
            ki_volt_per_count_s: 6e-3,
            max_volts: 10.0,
            rate_limit_volt_per_s: 60.0,
            tracking_time_s: 0.05,
        }
    }
}

/// One finger's PI controller.
///
/// `V = k_p e + I`, `I` integrating `k_i e` (eq. 6.9). When the output
/// saturates or hits the rate limit, the integral is pulled towards the
/// applied output (back-calculation), so it never winds up.
#[derive(Clone, Debug, PartialEq)]
pub struct PiController {
    cfg: PiConfig,
    integral_v: f64,
    output_v: f64,
}

/// The result of one controller step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PiOutput {
    /// Voltage to apply (V).
    pub volts: f64,
    /// True when saturation or the rate limit changed the PI output.
    pub limited: bool,
}

impl PiController {
    /// A controller at rest (zero integral, zero output).
    pub fn new(cfg: PiConfig) -> PiController {
        PiController { cfg, integral_v: 0.0, output_v: 0.0 }
    }

    /// Starts from a given applied voltage without a bump: the integral takes
    /// the voltage, so the first output equals `volts` plus the P term.
    pub fn reset_to(&mut self, volts: f64) {
        self.integral_v = volts;
        self.output_v = volts;
    }

    /// The integral term (V).
    pub fn integral_v(&self) -> f64 {
        self.integral_v
    }

    /// One step with the error `e = desired - achieved` (counts) over `dt_s`.
    pub fn step(&mut self, error_counts: f64, dt_s: f64) -> PiOutput {
        let c = &self.cfg;
        let error = if error_counts.is_finite() { error_counts } else { 0.0 };
        self.integral_v += c.ki_volt_per_count_s * error * dt_s;
        let raw = c.kp_volt_per_count * error + self.integral_v;
        let max_step = c.rate_limit_volt_per_s * dt_s;
        let applied =
            raw.clamp(self.output_v - max_step, self.output_v + max_step).clamp(-c.max_volts, c.max_volts);
        self.integral_v += (applied - raw) * (dt_s / c.tracking_time_s).min(1.0);
        self.output_v = applied;
        PiOutput { volts: applied, limited: (applied - raw).abs() > 1e-12 }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unlimited() -> PiConfig {
        PiConfig {
            kp_volt_per_count: 0.5,
            ki_volt_per_count_s: 2.0,
            max_volts: 1e9,
            rate_limit_volt_per_s: 1e12,
            tracking_time_s: 0.05,
        }
    }

    #[test]
    fn without_limits_it_is_the_pi_law() {
        let mut pi = PiController::new(unlimited());
        let mut integral = 0.0;
        for k in 0..50 {
            let e = (k as f64 * 0.3).sin();
            integral += e * 0.01;
            let out = pi.step(e, 0.01);
            assert!((out.volts - (0.5 * e + 2.0 * integral)).abs() < 1e-12);
            assert!(!out.limited);
        }
    }

    #[test]
    fn saturates_and_does_not_wind_up() {
        let cfg = PiConfig { max_volts: 1.0, ..unlimited() };
        let mut pi = PiController::new(cfg);
        for _ in 0..1000 {
            let out = pi.step(10.0, 0.01);
            assert!(out.volts <= 1.0);
        }
        // The integral stays near the saturation level, so a reversed error
        // pulls the output off the limit at once.
        assert!(pi.integral_v() < 1.0 + 10.0 * 0.5, "{}", pi.integral_v());
        let out = pi.step(-10.0, 0.01);
        assert!(out.volts < 0.0, "{}", out.volts);
    }

    #[test]
    fn rate_limit_bounds_each_step() {
        let cfg = PiConfig { rate_limit_volt_per_s: 10.0, ..unlimited() };
        let mut pi = PiController::new(cfg);
        let out = pi.step(100.0, 0.01);
        assert!((out.volts - 0.1).abs() < 1e-12 && out.limited);
    }

    #[test]
    fn nan_error_is_ignored() {
        let mut pi = PiController::new(unlimited());
        assert_eq!(pi.step(f64::NAN, 0.01).volts, 0.0);
    }
}
