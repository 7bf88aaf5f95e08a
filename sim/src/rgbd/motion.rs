//! Fast 6D object motion like the Fast-YCB sequences (thesis Sec. 5.5.1:
//! linear velocities up to 63 cm/s, angular velocities up to 266 deg/s), and
//! [`FastSequence`], which renders it at 30 Hz.

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};
use slidetrack_core::{CameraIntrinsics, MarkerPattern, ObjectTruth, RgbdFrame, TimeNs};
use slidetrack_render::{TriangleMesh, splitmix64};

use super::decal::MarkerDecal;
use super::error::RgbdSimError;
use super::scene::{RgbdScene, RgbdSceneConfig};
use super::texture::Texture;

/// The simulated objects, shaped like the Fast-YCB ones (boxes and cans of
/// the YCB set), each with its own texture colours.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SimObjectKind {
    /// 003 cracker box, 16 x 6 x 21 cm.
    CrackerBox,
    /// 004 sugar box, 9 x 4 x 17.5 cm.
    SugarBox,
    /// 005 tomato soup can, 6.8 cm across, 10 cm high.
    SoupCan,
    /// 006 mustard bottle, as a 9.5 x 6 x 19 cm box.
    MustardBottle,
    /// 009 gelatin box, 9 x 7.3 x 2.8 cm.
    GelatinBox,
    /// 010 potted meat can, as a 10 x 5 x 8.5 cm box.
    MeatCan,
}

impl SimObjectKind {
    /// Every kind, in the order of the YCB numbers.
    pub const ALL: [SimObjectKind; 6] = [
        SimObjectKind::CrackerBox,
        SimObjectKind::SugarBox,
        SimObjectKind::SoupCan,
        SimObjectKind::MustardBottle,
        SimObjectKind::GelatinBox,
        SimObjectKind::MeatCan,
    ];

    /// The name used on the command line.
    pub fn name(self) -> &'static str {
        match self {
            SimObjectKind::CrackerBox => "cracker_box",
            SimObjectKind::SugarBox => "sugar_box",
            SimObjectKind::SoupCan => "soup_can",
            SimObjectKind::MustardBottle => "mustard_bottle",
            SimObjectKind::GelatinBox => "gelatin_box",
            SimObjectKind::MeatCan => "meat_can",
        }
    }

    /// The kind named `name`.
    pub fn from_name(name: &str) -> Option<SimObjectKind> {
        SimObjectKind::ALL.into_iter().find(|k| k.name() == name)
    }

    /// The object's mesh, object frame centred in its bounding box.
    pub fn mesh(self) -> TriangleMesh {
        match self {
            SimObjectKind::CrackerBox => TriangleMesh::cuboid([0.16, 0.06, 0.21]),
            SimObjectKind::SugarBox => TriangleMesh::cuboid([0.09, 0.04, 0.175]),
            SimObjectKind::SoupCan => TriangleMesh::cylinder(0.034, 0.10, 32),
            SimObjectKind::MustardBottle => TriangleMesh::cuboid([0.095, 0.06, 0.19]),
            SimObjectKind::GelatinBox => TriangleMesh::cuboid([0.09, 0.073, 0.028]),
            SimObjectKind::MeatCan => TriangleMesh::cuboid([0.10, 0.05, 0.085]),
        }
    }

    /// The object's texture.
    pub fn texture(self, seed: u64) -> Texture {
        let (base, accent) = match self {
            SimObjectKind::CrackerBox => ([0.85, 0.2, 0.15], [0.95, 0.85, 0.3]),
            SimObjectKind::SugarBox => ([0.95, 0.9, 0.6], [0.2, 0.45, 0.8]),
            SimObjectKind::SoupCan => ([0.8, 0.15, 0.12], [0.95, 0.95, 0.9]),
            SimObjectKind::MustardBottle => ([0.95, 0.8, 0.1], [0.3, 0.2, 0.1]),
            SimObjectKind::GelatinBox => ([0.9, 0.3, 0.5], [0.95, 0.9, 0.9]),
            SimObjectKind::MeatCan => ([0.2, 0.35, 0.75], [0.9, 0.8, 0.2]),
        };
        Texture::packaging(seed ^ self as u64, base, accent, 0.12)
    }
}

/// Settings of a fast motion.
#[derive(Clone, Debug, PartialEq)]
pub struct FastMotionConfig {
    /// Centre of the motion, camera frame (m).
    pub centre_m: [f64; 3],
    /// Largest excursion from the centre along each camera axis (m).
    pub amplitude_m: [f64; 3],
    /// Peak linear speed over the sequence (m/s).
    pub max_speed_mps: f64,
    /// Peak angular speed over the sequence (deg/s).
    pub max_angular_speed_dps: f64,
    /// Length of the motion (s).
    pub duration_s: f64,
    /// Seed of the frequencies, phases and the initial orientation.
    pub seed: u64,
}

impl Default for FastMotionConfig {
    fn default() -> FastMotionConfig {
        FastMotionConfig {
            centre_m: [0.0, 0.0, 0.75],
            amplitude_m: [0.15, 0.09, 0.1],
            max_speed_mps: 0.6,
            max_angular_speed_dps: 270.0,
            duration_s: 10.0,
            seed: 1,
        }
    }
}

/// One sinusoid `a sin(2π f t + φ)`.
#[derive(Clone, Copy, Debug)]
struct Wave {
    amplitude: f64,
    frequency_hz: f64,
    phase: f64,
}

impl Wave {
    fn value(&self, t: f64) -> f64 {
        self.amplitude * (std::f64::consts::TAU * self.frequency_hz * t + self.phase).sin()
    }
    fn rate(&self, t: f64) -> f64 {
        self.amplitude
            * std::f64::consts::TAU
            * self.frequency_hz
            * (std::f64::consts::TAU * self.frequency_hz * t + self.phase).cos()
    }
}

/// A time warp `s(t)` with rate `ṡ = 1 + A cos(2π t / T + φ)`: the motion
/// runs through slow and fast phases, as hand-held objects do.
#[derive(Clone, Copy, Debug)]
struct Warp {
    amplitude: f64,
    period_s: f64,
    phase: f64,
}

impl Warp {
    fn s(&self, t: f64) -> f64 {
        let w = std::f64::consts::TAU / self.period_s;
        t + self.amplitude / w * ((w * t + self.phase).sin() - self.phase.sin())
    }
    fn rate(&self, t: f64) -> f64 {
        1.0 + self.amplitude * (std::f64::consts::TAU / self.period_s * t + self.phase).cos()
    }
}

/// A smooth, fast 6D trajectory: sums of sinusoids for the position and the
/// angular velocity along a warped time (slow and fast phases), scaled to the
/// configured peak speeds; the orientation is the exact integral of the
/// angular velocity (1 kHz exponential steps).
#[derive(Clone, Debug)]
pub struct FastMotion {
    centre: Vector3<f64>,
    position: [[Wave; 2]; 3],
    angular: [[Wave; 2]; 3],
    warp: Warp,
    step_s: f64,
    /// The orientation along the warped time `s`, every `step_s`.
    orientations: Vec<UnitQuaternion<f64>>,
}

impl FastMotion {
    /// Draws a trajectory from `config.seed`.
    pub fn new(config: &FastMotionConfig) -> FastMotion {
        let mut state = config.seed ^ 0x6d6f_7469_6f6e;
        let mut uniform = move || {
            state = splitmix64(state);
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut waves = |scale: [f64; 3], low: f64, high: f64| -> [[Wave; 2]; 3] {
            std::array::from_fn(|axis| {
                std::array::from_fn(|k| Wave {
                    amplitude: scale[axis] * if k == 0 { 0.7 } else { 0.3 },
                    frequency_hz: low + (high - low) * uniform() * if k == 0 { 0.5 } else { 1.0 },
                    phase: std::f64::consts::TAU * uniform(),
                })
            })
        };
        let position = waves(config.amplitude_m, 0.25, 1.2);
        let angular = waves([1.0, 1.0, 1.0], 0.2, 0.9);
        let initial = UnitQuaternion::from_euler_angles(
            std::f64::consts::TAU * uniform(),
            std::f64::consts::PI * (uniform() - 0.5),
            std::f64::consts::TAU * uniform(),
        );
        let warp =
            Warp { amplitude: 0.75, period_s: 2.5 + uniform(), phase: std::f64::consts::TAU * uniform() };
        let duration = config.duration_s.max(0.1);
        let mut motion = FastMotion {
            centre: Vector3::from(config.centre_m),
            position,
            angular,
            warp,
            step_s: 1e-3,
            orientations: Vec::new(),
        };
        let peak = |f: &dyn Fn(f64) -> f64| {
            (0..=(duration * 200.0) as usize).map(|i| f(i as f64 / 200.0)).fold(0.0, f64::max)
        };
        let speed = peak(&|t| motion.linear_velocity(t).norm());
        if speed > 0.0 {
            let s = (config.max_speed_mps / speed).min(1.0);
            motion.position.iter_mut().flatten().for_each(|w| w.amplitude *= s);
        }
        let spin = peak(&|t| motion.angular_velocity(t).norm());
        if spin > 0.0 {
            let s = config.max_angular_speed_dps.to_radians() / spin;
            motion.angular.iter_mut().flatten().for_each(|w| w.amplitude *= s);
        }
        let steps = (motion.warp.s(duration) / motion.step_s).ceil() as usize + 2;
        let mut q = initial;
        motion.orientations.reserve(steps + 1);
        motion.orientations.push(q);
        for i in 0..steps {
            let s_mid = (i as f64 + 0.5) * motion.step_s;
            q = UnitQuaternion::from_scaled_axis(motion.path_angular_velocity(s_mid) * motion.step_s) * q;
            motion.orientations.push(q);
        }
        motion
    }

    /// `ω` along the warped time `s` (rad per unit of `s`).
    fn path_angular_velocity(&self, s: f64) -> Vector3<f64> {
        Vector3::from_fn(|a, _| self.angular[a].iter().map(|w| w.value(s)).sum::<f64>())
    }

    /// `ω(t)`, camera frame (rad/s).
    pub fn angular_velocity(&self, t_s: f64) -> Vector3<f64> {
        self.path_angular_velocity(self.warp.s(t_s)) * self.warp.rate(t_s)
    }

    /// `ṗ(t)`, camera frame (m/s).
    pub fn linear_velocity(&self, t_s: f64) -> Vector3<f64> {
        let s = self.warp.s(t_s);
        Vector3::from_fn(|a, _| self.position[a].iter().map(|w| w.rate(s)).sum::<f64>()) * self.warp.rate(t_s)
    }

    /// The pose and velocity at `t_s` seconds (clamped to the duration).
    pub fn truth(&self, t_s: f64) -> (Isometry3<f64>, Vector3<f64>, Vector3<f64>) {
        let t = t_s.max(0.0);
        let s = self.warp.s(t);
        let p =
            self.centre + Vector3::from_fn(|a, _| self.position[a].iter().map(|w| w.value(s)).sum::<f64>());
        let i = ((s / self.step_s).floor() as usize).min(self.orientations.len() - 1);
        let rest = s - i as f64 * self.step_s;
        let q = UnitQuaternion::from_scaled_axis(self.path_angular_velocity(s - rest / 2.0) * rest)
            * self.orientations[i];
        (Isometry3::from_parts(Translation3::from(p), q), self.linear_velocity(t), self.angular_velocity(t))
    }
}

/// Settings of a rendered fast sequence.
#[derive(Clone, Debug, PartialEq)]
pub struct FastSequenceConfig {
    /// The object.
    pub object: SimObjectKind,
    /// Its motion.
    pub motion: FastMotionConfig,
    /// The camera and its noise.
    pub scene: RgbdSceneConfig,
    /// Frame rate (Hz).
    pub fps: f64,
}

impl FastSequenceConfig {
    /// A VGA sequence of `object` at 30 Hz lasting `duration_s`, from `seed`.
    pub fn new(object: SimObjectKind, duration_s: f64, seed: u64) -> FastSequenceConfig {
        FastSequenceConfig {
            object,
            motion: FastMotionConfig { duration_s, seed, ..FastMotionConfig::default() },
            scene: RgbdSceneConfig::vga(seed),
            fps: 30.0,
        }
    }
}

/// A fast object seen by the simulated RGB-D camera, frame by frame.
pub struct FastSequence {
    config: FastSequenceConfig,
    scene: RgbdScene,
    motion: FastMotion,
}

impl FastSequence {
    /// Builds the scene and draws the motion.
    pub fn new(config: FastSequenceConfig) -> Result<FastSequence, RgbdSimError> {
        if !(config.fps > 0.0 && config.fps <= 1000.0) {
            return Err(RgbdSimError::OutOfRange { what: "fps", value: config.fps, expected: "0..1000 Hz" });
        }
        let texture = config.object.texture(config.scene.seed);
        let scene = RgbdScene::new(config.scene.clone(), config.object.mesh(), texture)?;
        let motion = FastMotion::new(&config.motion);
        Ok(FastSequence { config, scene, motion })
    }

    /// Number of frames.
    pub fn len(&self) -> usize {
        (self.config.motion.duration_s * self.config.fps).floor() as usize
    }

    /// No frames.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The intrinsics of colour and depth.
    pub fn intrinsics(&self) -> &CameraIntrinsics {
        &self.scene.config().intrinsics
    }

    /// The object's mesh.
    pub fn mesh(&self) -> &TriangleMesh {
        self.scene.mesh()
    }

    /// Prints the marker `pattern` (black square `size_m` per side) on the
    /// face that faces the camera most in the first frame; returns the
    /// decal, with its `object_from_marker`, or `None` when no face fits.
    pub fn print_marker(&mut self, pattern: MarkerPattern, size_m: f64) -> Option<&MarkerDecal> {
        let first = self.truth(0).camera_from_object;
        let decal = MarkerDecal::on_face_seen_at(pattern, size_m, self.scene.mesh(), &first)?;
        self.scene.set_marker(Some(decal));
        self.scene.marker()
    }

    /// The configuration.
    pub fn config(&self) -> &FastSequenceConfig {
        &self.config
    }

    /// The time of frame `k`.
    pub fn time(&self, k: usize) -> TimeNs {
        TimeNs((k as f64 / self.config.fps * 1e9).round() as u64)
    }

    /// The truth at frame `k`.
    pub fn truth(&self, k: usize) -> ObjectTruth {
        let t = self.time(k);
        let (camera_from_object, linear_velocity_mps, angular_velocity_radps) =
            self.motion.truth(t.0 as f64 * 1e-9);
        ObjectTruth { t, camera_from_object, linear_velocity_mps, angular_velocity_radps }
    }

    /// Renders frame `k`: the frame, the ground-truth mask (255 on the
    /// object) and the truth.
    pub fn frame(&self, k: usize) -> (RgbdFrame, Vec<u8>, ObjectTruth) {
        let truth = self.truth(k);
        let r = self.scene.render(&truth.camera_from_object, k as u64);
        let frame = RgbdFrame {
            t: truth.t,
            sequence: k as u64,
            color: r.color,
            depth: r.depth,
            intrinsics: self.intrinsics().clone(),
        };
        (frame, r.mask, truth)
    }
}
