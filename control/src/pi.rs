//! The PI law (6.9), with output saturation, a rate limit and
//! back-calculation anti-windup: a finger's voltage or a gripper's position.

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

/// The PI law in whatever unit its output drives (V for a finger's joint,
/// position steps for a gripper), with its limits in that unit.
#[derive(Clone, Debug, PartialEq)]
pub struct PiLaw {
    /// Proportional gain (output per count of z error).
    pub kp: f64,
    /// Integral gain (output per count-second).
    pub ki: f64,
    /// Smallest output.
    pub min: f64,
    /// Largest output.
    pub max: f64,
    /// Largest change of the output per second.
    pub rate_limit_per_s: f64,
    /// Anti-windup tracking time constant (s).
    pub tracking_time_s: f64,
}

impl From<&PiConfig> for PiLaw {
    fn from(c: &PiConfig) -> PiLaw {
        PiLaw {
            kp: c.kp_volt_per_count,
            ki: c.ki_volt_per_count_s,
            min: -c.max_volts,
            max: c.max_volts,
            rate_limit_per_s: c.rate_limit_volt_per_s,
            tracking_time_s: c.tracking_time_s,
        }
    }
}

/// One PI controller (a finger's joint voltage, or a gripper's position
/// beyond contact).
///
/// `u = k_p e + I`, `I` integrating `k_i e` (eq. 6.9). When the output
/// saturates or hits the rate limit, the integral is pulled towards the
/// applied output (back-calculation), so it never winds up.
#[derive(Clone, Debug, PartialEq)]
pub struct PiController {
    law: PiLaw,
    integral: f64,
    output: f64,
}

/// The result of one controller step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PiOutput {
    /// Output to apply (V for a finger, steps for a gripper).
    pub value: f64,
    /// True when saturation or the rate limit changed the PI output.
    pub limited: bool,
}

impl PiController {
    /// A finger's voltage controller at rest (zero integral, zero output).
    pub fn new(cfg: PiConfig) -> PiController {
        PiController::with_law(PiLaw::from(&cfg))
    }

    /// A controller of `law` at rest.
    pub fn with_law(law: PiLaw) -> PiController {
        PiController { law, integral: 0.0, output: 0.0 }
    }

    /// Starts from a given applied output without a bump: the integral takes
    /// the output, so the first output equals `value` plus the P term.
    pub fn reset_to(&mut self, value: f64) {
        self.integral = value;
        self.output = value;
    }

    /// The integral term (output units).
    pub fn integral(&self) -> f64 {
        self.integral
    }

    /// One step with the error `e = desired - achieved` (counts) over `dt_s`.
    pub fn step(&mut self, error_counts: f64, dt_s: f64) -> PiOutput {
        let c = &self.law;
        let error = if error_counts.is_finite() { error_counts } else { 0.0 };
        self.integral += c.ki * error * dt_s;
        let raw = c.kp * error + self.integral;
        let max_step = c.rate_limit_per_s * dt_s;
        let applied = raw.clamp(self.output - max_step, self.output + max_step).clamp(c.min, c.max);
        self.integral += (applied - raw) * (dt_s / c.tracking_time_s).min(1.0);
        self.output = applied;
        PiOutput { value: applied, limited: (applied - raw).abs() > 1e-12 }
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
            assert!((out.value - (0.5 * e + 2.0 * integral)).abs() < 1e-12);
            assert!(!out.limited);
        }
    }

    #[test]
    fn saturates_and_does_not_wind_up() {
        let cfg = PiConfig { max_volts: 1.0, ..unlimited() };
        let mut pi = PiController::new(cfg);
        for _ in 0..1000 {
            let out = pi.step(10.0, 0.01);
            assert!(out.value <= 1.0);
        }
        // The integral stays near the saturation level, so a reversed error
        // pulls the output off the limit at once.
        assert!(pi.integral() < 1.0 + 10.0 * 0.5, "{}", pi.integral());
        let out = pi.step(-10.0, 0.01);
        assert!(out.value < 0.0, "{}", out.value);
    }

    #[test]
    fn rate_limit_bounds_each_step() {
        let cfg = PiConfig { rate_limit_volt_per_s: 10.0, ..unlimited() };
        let mut pi = PiController::new(cfg);
        let out = pi.step(100.0, 0.01);
        assert!((out.value - 0.1).abs() < 1e-12 && out.limited);
    }

    #[test]
    fn nan_error_is_ignored() {
        let mut pi = PiController::new(unlimited());
        assert_eq!(pi.step(f64::NAN, 0.01).value, 0.0);
    }
}
