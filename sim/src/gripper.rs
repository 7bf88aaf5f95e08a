//! The simulated parallel gripper: two opposed pads closing symmetrically
//! under a position servo with the Robotiq 2F's speed and force limits and
//! its position steps (the `[sim.gripper]` table of a rig TOML).
//!
//! Closure `c` (m) is how far the opening is below the stroke: 0 fully open,
//! `stroke_m` fully closed; each pad travels `x = c / 2` from its open rest.
//!
//! - Setpoint: the requested closure `c_req = steps * step_m` (whole steps
//!   only) is approached by a setpoint `c_s` at the requested speed,
//!   `|dc_s/dt| <= v(speed)`.
//! - Servo, per pad: `u = clamp(k_s (c_s / 2 - x), -F_lim, F_lim)` (N), the
//!   force limit `F_lim = F(force)` of the request.
//! - Pads: overdamped, `b dx/dt = u - (F_n,left + F_n,right) / 2`, both pads
//!   at the same `x` (one motor, a symmetric linkage), integrated by implicit
//!   Euler (Newton iterations) so that the stiff servo and pad stay stable.
//!   The setpoint never runs more than `F_lim / k_s` ahead of (or behind)
//!   the pads (anti-windup: a gripper stopped on an object opens at once).
//! - Pad contact: Hertz, `F = k delta^1.5` with `delta = x - gap + h` (m),
//!   `gap = (stroke - contact_opening) / 2`, `h` the texture height under the
//!   pad. The object is free across the grip, so it centres itself until both
//!   pads press alike: each pad's normal force is the mean of the two, and
//!   each pad is indented as much. At rest that grip force is `u`, never
//!   above `F_lim`.
//! - Motor current: `I = current_ma_per_n |u|` (mA).

use serde::{Deserialize, Serialize};
use slidetrack_core::{GripperObject, GripperRequest, GripperSpec, GripperStatus};

/// Which hand the simulated rig has (`[sim] hand`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum HandKind {
    /// The thesis's hand: thumb, index and middle finger, each closed by a voltage.
    #[default]
    ThreeFinger,
    /// A two-pad parallel gripper under position control ([`GripperConfig`]).
    Gripper,
}

impl HandKind {
    /// True for the default hand (for leaving it out of written configurations).
    pub fn is_three_finger(&self) -> bool {
        *self == HandKind::ThreeFinger
    }
}

/// The simulated parallel gripper (`[sim.gripper]`). Defaults: a Robotiq
/// 2F-85 with a soft uSkin pad on each finger.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct GripperConfig {
    /// The largest position request, fully closed (steps).
    pub max_steps: u16,
    /// Opening between the pads when fully open (m).
    pub stroke_m: f64,
    /// Opening speed at the slowest and the fastest speed request, `[lo, hi]` (m/s).
    pub speed_range_mps: [f64; 2],
    /// Force limit at the weakest and the strongest force request, `[lo, hi]` (N).
    pub force_range_n: [f64; 2],
    /// Servo stiffness per pad: force per metre of pad travel behind its setpoint (N/m).
    pub servo_stiffness_n_per_m: f64,
    /// Viscous resistance of each pad to moving (N s/m).
    pub damping_n_s_per_m: f64,
    /// Opening at which the pads touch the object (m); left out: the object's width.
    pub contact_opening_m: Option<f64>,
    /// Hertz law of each pad, `F = k delta^1.5` (N/m^1.5).
    ///
    /// The default pad is soft (a uSkin patch on a Robotiq finger): 1 N
    /// indents it by 1.3 mm (k = 21 335). One position step moves each pad
    /// by 0.17 mm and so changes the grip force by `1.5 F step / (2 delta)`:
    /// 0.19 N at 1 N, a quarter of the box's weight (0.08 kg). A pad as stiff
    /// as the fingertips' (1 N at 0.5 mm) would change it by 0.5 N, two
    /// thirds of the weight, and the grasp could not be regulated between
    /// holding and sliding. Under the thicker skin (`pad_magnet_height_m`)
    /// a z reading then means 1.24 times the force it means on a fingertip
    /// (the same indentation over magnet height), so that the objects'
    /// grasp-strength ranges, tuned on three fingers whose index and middle
    /// press more than half the thumb's force at half its counts, give both
    /// hands about the same friction capacity. Tuned on 12 trials of each
    /// object: at 1.4 mm per newton the bottle and the mustard were not
    /// always lifted; at 1.3 mm all slid in at least 5 episodes a minute.
    pub pad_contact_stiffness_n_per_m15: f64,
    /// Tangential stiffness of each pad: shear = friction / stiffness (N/m).
    pub pad_shear_stiffness_n_per_m: f64,
    /// Distance between magnet and Hall chip of the pads' tactile modules
    /// (m); on a gripper it replaces `[sim.tactile] magnet_height_m`.
    pub pad_magnet_height_m: f64,
    /// Motor current per newton of servo force (mA/N).
    pub current_ma_per_n: f64,
}

impl Default for GripperConfig {
    fn default() -> Self {
        let robotiq = GripperSpec::robotiq_2f85();
        GripperConfig {
            max_steps: robotiq.max_steps,
            stroke_m: robotiq.stroke_m,
            speed_range_mps: [robotiq.speed_range_mps.0, robotiq.speed_range_mps.1],
            force_range_n: [robotiq.force_range_n.0, robotiq.force_range_n.1],
            // A pad lags its setpoint by 0.02 mm per newton, a tenth of a step.
            servo_stiffness_n_per_m: 5.0e4,
            damping_n_s_per_m: 20.0,
            contact_opening_m: None,
            pad_contact_stiffness_n_per_m15: 21335.0,
            pad_shear_stiffness_n_per_m: 1500.0,
            pad_magnet_height_m: 0.006,
            // 0.94 A at the 2F-85's 235 N.
            current_ma_per_n: 4.0,
        }
    }
}

impl GripperConfig {
    /// What the gripper accepts, as a driver reports it.
    pub fn spec(&self) -> GripperSpec {
        GripperSpec {
            max_steps: self.max_steps,
            stroke_m: self.stroke_m,
            speed_range_mps: (self.speed_range_mps[0], self.speed_range_mps[1]),
            force_range_n: (self.force_range_n[0], self.force_range_n[1]),
        }
    }

    /// The first invalid field, as `(field under sim.gripper, what is wrong)`.
    pub fn invalid_field(&self) -> Option<(&'static str, String)> {
        let positive = [
            ("stroke_m", self.stroke_m),
            ("servo_stiffness_n_per_m", self.servo_stiffness_n_per_m),
            ("damping_n_s_per_m", self.damping_n_s_per_m),
            ("pad_contact_stiffness_n_per_m15", self.pad_contact_stiffness_n_per_m15),
            ("pad_shear_stiffness_n_per_m", self.pad_shear_stiffness_n_per_m),
            ("pad_magnet_height_m", self.pad_magnet_height_m),
        ];
        if let Some((field, v)) = positive.iter().find(|(_, v)| !(v.is_finite() && *v > 0.0)) {
            return Some((field, format!("must be a positive number, got {v}")));
        }
        if self.max_steps == 0 {
            return Some(("max_steps", "must be at least 1".into()));
        }
        for (field, [lo, hi]) in
            [("speed_range_mps", self.speed_range_mps), ("force_range_n", self.force_range_n)]
        {
            if !(lo.is_finite() && hi.is_finite() && lo > 0.0 && lo <= hi) {
                return Some((field, format!("must be [lo, hi] with 0 < lo <= hi, got [{lo}, {hi}]")));
            }
        }
        if !(self.current_ma_per_n.is_finite() && self.current_ma_per_n >= 0.0) {
            return Some(("current_ma_per_n", format!("must be 0 or more, got {}", self.current_ma_per_n)));
        }
        match self.contact_opening_m {
            Some(w) if !(w.is_finite() && w > 0.0 && w < self.stroke_m) => Some((
                "contact_opening_m",
                format!("must be positive and below stroke_m ({} m), got {w}", self.stroke_m),
            )),
            _ => None,
        }
    }
}

/// The state of the gripper: its request, servo setpoint and pads.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct GripperState {
    /// The request being followed, its position clamped to `max_steps`.
    pub request: GripperRequest,
    /// Closure the servo is heading for now (m), moving towards the request.
    pub setpoint_closure_m: f64,
    /// Each pad's travel from its open rest position (m); the closure is twice it.
    pub pad_travel_m: f64,
    /// Each pad's speed over the last step (m/s), positive closing.
    pub pad_speed_mps: f64,
    /// Servo force on each pad (N), positive closing.
    pub servo_n: f64,
    /// Each pad's indentation into the object (m), `[left, right]`.
    pub indentation_m: [f64; 2],
    /// Each pad's normal force (N), `[left, right]`.
    pub normal_n: [f64; 2],
    /// Distance from each open pad to the object's surface (m).
    pub gap_m: f64,
}

/// A pad speed below this counts as stopped (m/s).
const STOPPED_MPS: f64 = 1e-3;

impl GripperState {
    /// An open gripper whose pads touch an object at `contact_opening_m`.
    pub fn open(cfg: &GripperConfig, contact_opening_m: f64) -> GripperState {
        GripperState { gap_m: ((cfg.stroke_m - contact_opening_m) / 2.0).max(0.0), ..GripperState::default() }
    }

    /// Follows `request` from now on, its position clamped to `max_steps`.
    pub fn command(&mut self, cfg: &GripperConfig, request: GripperRequest) {
        self.request =
            GripperRequest { position_steps: request.position_steps.min(cfg.max_steps), ..request };
    }

    /// Opening between the pads (m).
    pub fn opening_m(&self, cfg: &GripperConfig) -> f64 {
        cfg.stroke_m - 2.0 * self.pad_travel_m
    }

    /// Advances the servo and the pads over `dt_s`. `surface_m` is how far
    /// the object's surface under each pad stands out (texture);
    /// `in_contact` is false when there is no object.
    pub fn step(&mut self, cfg: &GripperConfig, surface_m: [f64; 2], in_contact: bool, dt_s: f64) {
        let spec = cfg.spec();
        let target = f64::from(self.request.position_steps) * spec.step_m();
        let max_move = spec.speed_mps(self.request.speed) * dt_s;
        self.setpoint_closure_m += (target - self.setpoint_closure_m).clamp(-max_move, max_move);
        let limit_n = spec.force_n(self.request.force);
        let x0 = self.pad_travel_m;
        let x_set = self.setpoint_closure_m / 2.0;
        let b_over_dt = cfg.damping_n_s_per_m / dt_s;
        let offsets = surface_m.map(|h| if in_contact { h - self.gap_m } else { f64::NEG_INFINITY });
        // Implicit Euler: r(x) = b (x - x0) / dt - u(x) + mean F_n(x) = 0;
        // r grows monotonically with x, so Newton's iterations converge.
        let mut x = x0;
        for _ in 0..12 {
            let (u, du) = servo(cfg.servo_stiffness_n_per_m, x_set - x, limit_n);
            let (f, df) = mean_contact(cfg, x, offsets);
            let step = (b_over_dt * (x - x0) - u + f) / (b_over_dt - du + df);
            x -= step;
            if step.abs() < 1e-13 {
                break;
            }
        }
        x = x.clamp(0.0, cfg.stroke_m / 2.0);
        let windup_m = 2.0 * limit_n / cfg.servo_stiffness_n_per_m;
        self.setpoint_closure_m = self.setpoint_closure_m.clamp(2.0 * x - windup_m, 2.0 * x + windup_m);
        self.pad_speed_mps = (x - x0) / dt_s;
        self.pad_travel_m = x;
        self.servo_n = servo(cfg.servo_stiffness_n_per_m, self.setpoint_closure_m / 2.0 - x, limit_n).0;
        let grip_n = mean_contact(cfg, x, offsets).0;
        let indentation_m = (grip_n / cfg.pad_contact_stiffness_n_per_m15).powf(2.0 / 3.0);
        self.normal_n = [grip_n; 2];
        self.indentation_m = [indentation_m; 2];
    }

    /// The gripper's status registers: object detection (`gOBJ`), position
    /// request and actual position in steps, motor current.
    pub fn status(&self, cfg: &GripperConfig) -> GripperStatus {
        let spec = cfg.spec();
        let closure = 2.0 * self.pad_travel_m;
        let target = f64::from(self.request.position_steps) * spec.step_m();
        let force_limited = self.servo_n.abs() >= spec.force_n(self.request.force) * (1.0 - 1e-9);
        let moving = self.setpoint_closure_m != target || self.pad_speed_mps.abs() > STOPPED_MPS;
        let in_contact = self.normal_n.iter().any(|n| *n > 0.0);
        let object = match () {
            _ if force_limited && in_contact && target > closure => GripperObject::ContactClosing,
            _ if force_limited && in_contact => GripperObject::ContactOpening,
            _ if moving => GripperObject::Moving,
            _ if in_contact => GripperObject::ContactClosing,
            _ => GripperObject::AtRequest,
        };
        let position = (closure / spec.step_m()).round().clamp(0.0, f64::from(cfg.max_steps));
        GripperStatus {
            activated: true,
            object,
            fault: 0,
            requested_steps: self.request.position_steps,
            position_steps: position as u16,
            current_ma: (cfg.current_ma_per_n * self.servo_n.abs()).round() as u32,
        }
    }
}

/// The servo force (N) for a pad `behind_m` behind its setpoint, and its
/// derivative with respect to the pad's travel (N/m).
fn servo(stiffness_n_per_m: f64, behind_m: f64, limit_n: f64) -> (f64, f64) {
    let u = stiffness_n_per_m * behind_m;
    if u.abs() >= limit_n { (limit_n.copysign(u), 0.0) } else { (u, -stiffness_n_per_m) }
}

/// Hertz contact force (N) and stiffness (N/m) at indentation `delta_m`.
fn hertz(k: f64, delta_m: f64) -> (f64, f64) {
    if delta_m <= 0.0 {
        return (0.0, 0.0);
    }
    let s = delta_m.sqrt();
    (k * delta_m * s, 1.5 * k * s)
}

/// The pads' mean normal force (N) and its derivative (N/m) at pad travel `x_m`.
fn mean_contact(cfg: &GripperConfig, x_m: f64, offsets: [f64; 2]) -> (f64, f64) {
    let [(f0, k0), (f1, k1)] = offsets.map(|o| hertz(cfg.pad_contact_stiffness_n_per_m15, x_m + o));
    ((f0 + f1) / 2.0, (k0 + k1) / 2.0)
}
