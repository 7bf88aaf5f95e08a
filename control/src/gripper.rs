//! The grasp on a position-controlled parallel gripper (Robotiq 2F): the PI
//! law (6.9) drives a position request around the position where both pads
//! first touched, instead of a joint voltage.
//!
//! A gripper has one actuator for two opposed pads, so the grasp strength it
//! regulates is the mean of the two pads' z: at rest both pads press with
//! the same normal force, and the partition for two opposed fingers gives
//! each the whole reference ([`crate::partition_two_opposed`]).

use serde::{Deserialize, Serialize};
use slidetrack_core::{ActuatorCommand, GripperRequest, GripperSpec};

use crate::pi::{PiController, PiLaw};

/// Settings of the grasp on a gripper (the `[protocol.gripper]` table of a
/// rig TOML; every field has a default). Positions are the gripper's
/// position steps (Robotiq `rPR`: 0 open .. 255 closed, about 0.33 mm of
/// opening per step on the 2F-85).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct GripperControlConfig {
    /// Position requested while the baseline is taken, and where closing
    /// starts (steps): just short of the object saves closing time.
    pub approach_steps: u16,
    /// How fast the request closes until both pads touch (steps/s); slower
    /// than the gripper's speed, so that the fingers are where the request
    /// is when contact is seen.
    pub close_rate_steps_per_s: f64,
    /// Speed request of every command (Robotiq `rSP`, 0-255).
    pub speed: u8,
    /// Force request of every command (Robotiq `rFR`, 0-255): the force
    /// limit, above what the grasp ever needs.
    pub force: u8,
    /// Proportional gain `k_p` (steps per count of z error).
    pub kp_steps_per_count: f64,
    /// Integral gain `k_i` (steps per count-second).
    pub ki_steps_per_count_s: f64,
    /// Deepest request beyond the contact position (steps).
    pub max_steps_beyond_contact: f64,
    /// Widest request short of the contact position (steps).
    pub max_steps_before_contact: f64,
    /// Largest change of the request per second (steps/s).
    pub rate_limit_steps_per_s: f64,
    /// Anti-windup tracking time constant (s).
    pub tracking_time_s: f64,
}

impl Default for GripperControlConfig {
    fn default() -> Self {
        GripperControlConfig {
            approach_steps: 0,
            close_rate_steps_per_s: 40.0,
            speed: 128,
            force: 128,
            kp_steps_per_count: 1.5e-3,
            ki_steps_per_count_s: 1.5e-2,
            max_steps_beyond_contact: 40.0,
            max_steps_before_contact: 10.0,
            rate_limit_steps_per_s: 200.0,
            tracking_time_s: 0.05,
        }
    }
}

/// The gripper side of the protocol: where the request is, where contact
/// was, and the PI controller of the position beyond contact.
#[derive(Clone, Debug, PartialEq)]
pub struct GripperGrasp {
    cfg: GripperControlConfig,
    spec: GripperSpec,
    /// The request while closing (steps, fractional).
    closing_steps: f64,
    /// The request when both pads first touched (steps).
    contact_steps: Option<f64>,
    pi: PiController,
}

impl GripperGrasp {
    /// A grasp on the gripper `spec`, open at `cfg.approach_steps`.
    pub fn new(cfg: GripperControlConfig, spec: GripperSpec) -> GripperGrasp {
        let pi = PiController::with_law(PiLaw {
            kp: cfg.kp_steps_per_count,
            ki: cfg.ki_steps_per_count_s,
            min: -cfg.max_steps_before_contact,
            max: cfg.max_steps_beyond_contact,
            rate_limit_per_s: cfg.rate_limit_steps_per_s,
            tracking_time_s: cfg.tracking_time_s,
        });
        let closing_steps = f64::from(cfg.approach_steps.min(spec.max_steps));
        GripperGrasp { cfg, spec, closing_steps, contact_steps: None, pi }
    }

    /// The request while zeroing: open at the approach position.
    pub fn approach(&self) -> ActuatorCommand {
        self.request(f64::from(self.cfg.approach_steps))
    }

    /// The request while closing towards the object over `dt_s`: it moves at
    /// the closing rate until `all_touch`, then stays where contact was.
    pub fn close(&mut self, all_touch: bool, dt_s: f64) -> ActuatorCommand {
        if all_touch && self.contact_steps.is_none() {
            self.contact_steps = Some(self.closing_steps);
            self.pi.reset_to(0.0);
        }
        if self.contact_steps.is_none() {
            self.closing_steps = (self.closing_steps + self.cfg.close_rate_steps_per_s * dt_s)
                .min(f64::from(self.spec.max_steps));
        }
        self.request(self.closing_steps)
    }

    /// The request after contact: the contact position plus the PI output on
    /// `error_counts = reference - mean pad z` over `dt_s`.
    pub fn grasp(&mut self, error_counts: f64, dt_s: f64) -> ActuatorCommand {
        let contact = self.contact_steps.unwrap_or(self.closing_steps);
        let beyond = self.pi.step(error_counts, dt_s).value;
        self.request(contact + beyond)
    }

    /// The position where both pads first touched (steps), once they have.
    pub fn contact_steps(&self) -> Option<f64> {
        self.contact_steps
    }

    /// A request at `steps` (rounded to whole steps, within the stroke).
    fn request(&self, steps: f64) -> ActuatorCommand {
        let max = f64::from(self.spec.max_steps);
        let position = if steps.is_finite() { steps.round().clamp(0.0, max) } else { 0.0 };
        ActuatorCommand::Gripper(GripperRequest {
            position_steps: position as u16,
            speed: self.cfg.speed,
            force: self.cfg.force,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn position(c: ActuatorCommand) -> u16 {
        match c {
            ActuatorCommand::Gripper(r) => r.position_steps,
            other => panic!("not a gripper request: {other:?}"),
        }
    }

    fn grasp() -> GripperGrasp {
        let cfg =
            GripperControlConfig { approach_steps: 100, close_rate_steps_per_s: 50.0, ..Default::default() };
        GripperGrasp::new(cfg, GripperSpec::robotiq_2f85())
    }

    #[test]
    fn closes_at_the_rate_then_holds_the_contact_position() {
        let mut g = grasp();
        assert_eq!(position(g.approach()), 100);
        for _ in 0..10 {
            g.close(false, 0.01);
        }
        // 10 ticks of 0.01 s at 50 steps/s: 5 steps.
        assert_eq!(position(g.close(true, 0.01)), 105);
        assert_eq!(g.contact_steps(), Some(105.0));
        assert_eq!(position(g.close(true, 0.01)), 105);
    }

    #[test]
    fn grasp_is_contact_plus_pi_within_the_limits() {
        let mut g = grasp();
        g.close(true, 0.01);
        // P + I on the first tick: 1.5e-3 * 2000 + 1.5e-2 * 2000 * 0.01 =
        // 3.3 steps, rate-limited to 200 steps/s * 0.01 s = 2.
        assert_eq!(position(g.grasp(2000.0, 0.01)), 102);
        // Back-calculation pulled the integral from 0.3 towards the applied 2:
        // 0.3 + (2 - 3.3) * 0.01 / 0.05 = 0.04 steps, which rounds to contact.
        assert_eq!(position(g.grasp(0.0, 0.01)), 100);
        for _ in 0..1000 {
            g.grasp(1e6, 0.01);
        }
        assert_eq!(position(g.grasp(1e6, 0.01)), 140, "saturates 40 steps beyond contact");
        for _ in 0..1000 {
            g.grasp(-1e6, 0.01);
        }
        assert_eq!(position(g.grasp(-1e6, 0.01)), 90, "and 10 short of it");
    }

    #[test]
    fn requests_stay_within_the_stroke() {
        let cfg = GripperControlConfig {
            approach_steps: 250,
            max_steps_beyond_contact: 100.0,
            ..Default::default()
        };
        let mut g = GripperGrasp::new(cfg, GripperSpec::robotiq_2f85());
        g.close(true, 0.01);
        for _ in 0..100 {
            g.grasp(1e6, 0.01);
        }
        assert_eq!(position(g.grasp(1e6, 0.01)), 255);
    }
}
