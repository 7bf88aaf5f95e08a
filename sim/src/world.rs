//! The simulated grasp: three fingers (or the two pads of a parallel
//! gripper), an object under gravity between them, friction at each
//! fingertip, and the tactile modules that feel it.
//!
//! On a gripper the thumb's slot is the left pad and the index's the right
//! pad; the middle finger's slot carries nothing (no contact, no tactile
//! module, zero normal and friction force in the truth).

use std::collections::VecDeque;

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use slidetrack_core::{FingerVolts, GripperRequest, GripperStatus, SimTruth, TimeNs};

use super::config::SimRigConfig;
use super::finger::FingerState;
use super::friction::{LuGreContact, LuGreParams};
use super::gripper::{GripperState, HandKind};
use super::object::ObjectConfig;
use super::surface::SurfaceProfile;
use super::tactile_model::{ContactDeformation, TactileModelConfig, TactileModule};

/// Independent random streams of one trial, so that turning the camera off
/// (or on) does not change the tactile data.
#[derive(Clone, Copy, Debug)]
pub enum Stream {
    /// Per-trial parameter draws (mass, friction, sensor gains, baselines).
    Trial = 1,
    /// Tactile noise, drift, vibration and spikes.
    Tactile = 2,
    /// Camera noise.
    Camera = 3,
}

/// A seed for `stream` of `trial` under the session seed (SplitMix64 mixing).
pub fn stream_seed(seed: u64, trial: u32, stream: Stream) -> u64 {
    let mut z = seed
        .wrapping_mul(0x9E37_79B9_7F4A_7C15)
        .wrapping_add(u64::from(trial).wrapping_mul(0xBF58_476D_1CE4_E5B9))
        .wrapping_add(stream as u64);
    for _ in 0..2 {
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
    }
    z
}

/// The state of the whole simulated grasp.
pub struct SimWorld {
    cfg: SimRigConfig,
    object: ObjectConfig,
    mass_kg: f64,
    lugre: LuGreParams,
    fingers: [FingerState; 3],
    /// The gripper's servo and pads, when the hand is a gripper (the
    /// fingers then stay open and idle).
    gripper: Option<GripperState>,
    contacts: [LuGreContact; 3],
    friction_n: [f64; 3],
    /// Per finger, one module per taxel of its patch (one for the thesis's hand).
    modules: [Vec<TactileModule>; 3],
    /// The modules' parameters (`[sim.tactile]`, on a gripper with its pads' magnet height).
    tactile_cfg: TactileModelConfig,
    /// The share of the contact each taxel of a patch feels.
    taxel_shares: Vec<f64>,
    surfaces: [SurfaceProfile; 3],
    tactile_rng: ChaCha8Rng,
    volts: FingerVolts,
    position_m: f64,
    velocity_mps: f64,
    supported: bool,
    lift_timer_s: f64,
    dropped: bool,
    t_ns: u64,
    dt_ns: u64,
    last_scan_ns: u64,
    frame_period_ns: Option<f64>,
    next_frame: u64,
    frames: VecDeque<(TimeNs, u64, f64)>,
}

impl SimWorld {
    /// A new trial: the object rests on its support between the open fingers.
    pub fn new(cfg: &SimRigConfig, object: &ObjectConfig, seed: u64, trial: u32) -> SimWorld {
        let mut rng = ChaCha8Rng::seed_from_u64(stream_seed(seed, trial, Stream::Trial));
        let j = &object.jitter;
        let mut jitter = |rel: f64| 1.0 + if rel > 0.0 { rng.random_range(-rel..=rel) } else { 0.0 };
        let mass_kg = object.mass_kg * jitter(j.mass_rel);
        let lugre = LuGreParams::from_config(&object.friction, jitter(j.friction_rel));
        let taxel_shares = cfg.tactile.patch.map_or_else(|| vec![1.0], |p| p.taxel_weights());
        let gripper = (cfg.hand == HandKind::Gripper)
            .then(|| GripperState::open(&cfg.gripper, cfg.contact_opening_m(object)));
        let sensed_fingers = if gripper.is_some() { 2 } else { 3 };
        let modules = [0, 1, 2].map(|f| {
            (0..if f < sensed_fingers { taxel_shares.len() } else { 0 })
                .map(|taxel| TactileModule::draw(&cfg.tactile, f, taxel, j.sensor_gain_rel, &mut rng))
                .collect()
        });
        let surfaces = [0, 1, 2].map(|_| SurfaceProfile::draw(&object.surface, &mut rng));
        let dt_ns = (1e9 / cfg.physics_rate_hz).round().max(1.0) as u64;
        let mut tactile_cfg = cfg.tactile.clone();
        if gripper.is_some() {
            tactile_cfg.magnet_height_m = cfg.gripper.pad_magnet_height_m;
        }
        SimWorld {
            cfg: cfg.clone(),
            object: object.clone(),
            mass_kg,
            lugre,
            fingers: [FingerState::default(); 3],
            gripper,
            contacts: [LuGreContact::default(); 3],
            friction_n: [0.0; 3],
            modules,
            tactile_cfg,
            taxel_shares,
            surfaces,
            tactile_rng: ChaCha8Rng::seed_from_u64(stream_seed(seed, trial, Stream::Tactile)),
            volts: [0.0; 3],
            position_m: 0.0,
            velocity_mps: 0.0,
            supported: true,
            lift_timer_s: 0.0,
            dropped: false,
            t_ns: 0,
            dt_ns,
            last_scan_ns: 0,
            frame_period_ns: None,
            next_frame: 0,
            frames: VecDeque::new(),
        }
    }

    /// Records the object position at every multiple of `1 / fps` from now on,
    /// for a camera to render ([`SimWorld::pop_frame`]).
    pub fn capture_frames(&mut self, fps: f64) {
        self.frame_period_ns = Some(1e9 / fps);
    }

    /// The oldest captured frame: exposure time, frame number (from 0) and
    /// object travel (m).
    pub fn pop_frame(&mut self) -> Option<(TimeNs, u64, f64)> {
        self.frames.pop_front()
    }

    /// Sets the proximal-joint voltages (V), already saturated by the hand.
    pub fn set_volts(&mut self, volts: FingerVolts) {
        self.volts = volts;
    }

    /// Sets the gripper's request (its position clamped to `max_steps`);
    /// false, and nothing changes, when the hand is not a gripper.
    pub fn command_gripper(&mut self, request: GripperRequest) -> bool {
        let Some(g) = self.gripper.as_mut() else { return false };
        g.command(&self.cfg.gripper, request);
        true
    }

    /// The gripper's state, when the hand is a gripper.
    pub fn gripper(&self) -> Option<&GripperState> {
        self.gripper.as_ref()
    }

    /// The gripper's status registers and its opening (m), when the hand is a gripper.
    pub fn gripper_status(&self) -> Option<(GripperStatus, f64)> {
        let g = self.gripper.as_ref()?;
        Some((g.status(&self.cfg.gripper), g.opening_m(&self.cfg.gripper)))
    }

    /// The rig's settings.
    pub fn config(&self) -> &SimRigConfig {
        &self.cfg
    }

    /// The trial's object after jitter: mass (kg).
    pub fn mass_kg(&self) -> f64 {
        self.mass_kg
    }

    /// Current physics time.
    pub fn now(&self) -> TimeNs {
        TimeNs(self.t_ns)
    }

    /// Steps the physics at its fixed rate until `t` (never backwards).
    pub fn advance_to(&mut self, t: TimeNs) {
        while self.t_ns + self.dt_ns <= t.0 {
            let p_before = self.position_m;
            self.step(self.dt_ns as f64 * 1e-9);
            self.t_ns += self.dt_ns;
            self.capture(p_before);
        }
    }

    fn capture(&mut self, p_before: f64) {
        let Some(period) = self.frame_period_ns else {
            return;
        };
        loop {
            let t_frame = (self.next_frame as f64 * period).round() as u64;
            if t_frame > self.t_ns {
                break;
            }
            // Linear interpolation inside the step that crossed the frame time.
            let t0 = self.t_ns - self.dt_ns;
            let s = (t_frame.saturating_sub(t0)) as f64 / self.dt_ns as f64;
            let p = p_before + s * (self.position_m - p_before);
            self.frames.push_back((TimeNs(t_frame), self.next_frame, p));
            self.next_frame += 1;
        }
    }

    fn step(&mut self, dt_s: f64) {
        let in_contact = !self.dropped;
        if let Some(g) = self.gripper.as_mut() {
            let heights = [0, 1].map(|f| self.surfaces[f].height_and_slope(self.position_m).0);
            g.step(&self.cfg.gripper, heights, in_contact, dt_s);
        } else {
            for (f, finger) in self.fingers.iter_mut().enumerate() {
                let (height, _) = self.surfaces[f].height_and_slope(self.position_m);
                finger.step(self.cfg.finger(f), self.volts[f], height, in_contact, dt_s);
            }
        }
        let normal = self.normal_n();
        let g = self.cfg.gravity_mps2;
        if self.supported {
            self.update_support(&normal, dt_s);
            self.friction_n = [0.0; 3];
            return;
        }
        if self.dropped {
            self.velocity_mps += g * dt_s;
            self.position_m += self.velocity_mps * dt_s;
            self.friction_n = [0.0; 3];
            return;
        }
        let p = &self.lugre;
        let scale = self.object.friction.profile_factor(self.position_m);
        let v = self.velocity_mps;
        let gv = p.stribeck(v, scale);
        // Bristle spring and the explicit part of the bristle damping, with the
        // velocity-proportional damping (sigma1 + sigma2) taken implicitly.
        let mut force_explicit = 0.0;
        let mut damping = 0.0;
        for (c, &n) in self.contacts.iter().zip(&normal) {
            force_explicit +=
                n * (p.sigma0_per_m * c.z_m - p.sigma1_s_per_m * p.sigma0_per_m * v.abs() * c.z_m / gv);
            damping += n * (p.sigma1_s_per_m + p.sigma2_s_per_m);
        }
        let m = self.mass_kg;
        let v_new = (v + dt_s * (g - force_explicit / m)) / (1.0 + dt_s * damping / m);
        let g_new = p.stribeck(v_new, scale);
        for (f, c) in self.contacts.iter_mut().enumerate() {
            c.step(p, v_new, g_new, dt_s);
            self.friction_n[f] = c.force(p, v_new, normal[f]);
        }
        self.velocity_mps = v_new;
        self.position_m += v_new * dt_s;
        if self.position_m > self.object.geometry.slide_range_m {
            self.dropped = true;
        }
    }

    /// The arm lifts the object once the grasp could hold it with a margin
    /// for a while; until then the support carries the weight.
    fn update_support(&mut self, normal: &[f64; 3], dt_s: f64) {
        let capacity: f64 = normal.iter().map(|n| n * self.lugre.mu_static).sum();
        let weight = self.mass_kg * self.cfg.gravity_mps2;
        if capacity >= self.cfg.lift_margin * weight {
            self.lift_timer_s += dt_s;
            if self.lift_timer_s >= self.cfg.lift_hold_s {
                self.supported = false;
            }
        } else {
            self.lift_timer_s = 0.0;
        }
    }

    /// Each contact's normal force (N), thumb (left pad), index (right pad), middle.
    fn normal_n(&self) -> [f64; 3] {
        match &self.gripper {
            Some(g) => [g.normal_n[0], g.normal_n[1], 0.0],
            None => self.fingers.map(|f| f.normal_n),
        }
    }

    /// Each contact's pad indentation (m), thumb (left pad), index (right pad), middle.
    fn indentation_m(&self) -> [f64; 3] {
        match &self.gripper {
            Some(g) => [g.indentation_m[0], g.indentation_m[1], 0.0],
            None => self.fingers.map(|f| f.indentation_m),
        }
    }

    /// Tangential stiffness of the pad at contact `f` (N/m).
    fn pad_shear_stiffness_n_per_m(&self, f: usize) -> f64 {
        match &self.gripper {
            Some(_) => self.cfg.gripper.pad_shear_stiffness_n_per_m,
            None => self.cfg.finger(f).pad_shear_stiffness_n_per_m,
        }
    }

    /// Each fingertip's travel from its open rest position (m), thumb, index,
    /// middle; on a gripper, the left and right pad's and 0.
    pub fn finger_travel_m(&self) -> [f64; 3] {
        match &self.gripper {
            Some(g) => [g.pad_travel_m, g.pad_travel_m, 0.0],
            None => self.fingers.map(|f| f.position_m),
        }
    }

    /// The truth now.
    pub fn truth(&self) -> SimTruth {
        SimTruth {
            t: TimeNs(self.t_ns),
            position_m: self.position_m,
            velocity_mps: self.velocity_mps,
            supported: self.supported,
            dropped: self.dropped,
            normal_n: self.normal_n(),
            friction_n: self.friction_n,
        }
    }

    /// The force on every taxel now (N), in each module's frame (x, y, z),
    /// in the order of [`SimWorld::scan_tactile`]: the contact's force
    /// (tangential along the sliding axis, none lateral, normal) split over
    /// a patch's taxels by their shares (the shares of a patch sum to its
    /// contact force) and turned by the module's mounting rotation. The
    /// reference of `slidetrack calibrate tactile`; draws no random numbers.
    pub fn taxel_forces_n(&self) -> Vec<[f64; 3]> {
        let normal = self.normal_n();
        let taxels = self.taxel_shares.len() as f64;
        let mut out = Vec::with_capacity(3 * self.taxel_shares.len());
        for (f, (modules, normal_n)) in self.modules.iter().zip(normal).enumerate() {
            let tangential_n = self.tangential_n(f, normal_n);
            for (module, share) in modules.iter().zip(&self.taxel_shares) {
                let k = share / taxels;
                out.push(module.force_in_module_frame([k * tangential_n, 0.0, k * normal_n]));
            }
        }
        out
    }

    /// The contact force of finger `f` along the sliding axis (N): friction,
    /// and on a sloped patch of texture the lean of the normal force.
    fn tangential_n(&self, f: usize, normal_n: f64) -> f64 {
        let (_, slope) = self.surfaces[f].height_and_slope(self.position_m);
        self.friction_n[f] + normal_n * slope
    }

    /// One scan of every taxel at the current time, finger after finger
    /// (thumb, index, middle; on a gripper: left pad, right pad), taxels row
    /// by row.
    pub fn scan_tactile(&mut self) -> Vec<[u16; 3]> {
        let dt_s = (self.t_ns - self.last_scan_ns.min(self.t_ns)) as f64 * 1e-9;
        self.last_scan_ns = self.t_ns;
        let t_s = self.t_ns as f64 * 1e-9;
        let mut raw = Vec::with_capacity(3 * self.taxel_shares.len());
        let normal = self.normal_n();
        let indentation = self.indentation_m();
        for f in 0..3 {
            // On a sloped patch of texture the contact force leans along the
            // sliding axis and shears the pad with it.
            let tangential_n = self.tangential_n(f, normal[f]);
            let deformation = ContactDeformation {
                indentation_m: indentation[f],
                shear_m: tangential_n / self.pad_shear_stiffness_n_per_m(f),
                slip_speed_mps: if self.supported { 0.0 } else { self.velocity_mps },
            };
            for (module, share) in self.modules[f].iter_mut().zip(&self.taxel_shares) {
                raw.push(module.sample_share(
                    &self.tactile_cfg,
                    &deformation,
                    *share,
                    t_s,
                    dt_s.max(1e-6),
                    &mut self.tactile_rng,
                ));
            }
        }
        raw
    }
}
