//! Arguments of the commands that run the experiment or its devices:
//! `collect`, `record`, `track`, `demo`, `bench`.

use std::path::PathBuf;

use clap::{Args, ValueEnum};
use slidetrack_experiment::vision::camera_vision::CameraVisionOptions;
use slidetrack_experiment::vision::{Measurements, PoseReset, TrackerKind};

use super::live::LiveArgs;

/// Which rig runs the trial, on the command line.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum RigArg {
    /// The simulated rig (physics model of the hand, object and sensors).
    Sim,
    /// The real rig, with the devices of the rig configuration.
    Hw,
    /// A recorded session (`--session`) played back through the same driver
    /// traits: the trackers run on it exactly as they ran live.
    Replay,
}

/// The experiment to run: rig, object, duration and how (`collect`, `track`).
#[derive(Debug, Args, Clone)]
pub struct ExperimentArgs {
    /// The rig to run on.
    #[arg(long, value_enum, default_value_t = RigArg::Sim)]
    pub rig: RigArg,
    /// Object: a built-in name (box, bottle, mustard) or a path to an object .toml.
    #[arg(long, default_value = "box")]
    pub object: String,
    /// Duration of the sliding cycles of each trial (s).
    #[arg(long, default_value_t = 60.0)]
    pub duration: f64,
    /// Seed of the simulated rig; the same seed gives the same data.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Rig configuration (TOML); the built-in simulated rig when absent.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Do not render or record the camera (much faster).
    #[arg(long)]
    pub no_camera: bool,
    /// Run the simulated rig in wall-clock time instead of as fast as possible.
    #[arg(long)]
    pub realtime: bool,
    /// Replace session files that already exist (refused otherwise).
    #[arg(long)]
    pub overwrite: bool,
    /// With `--rig replay`: the recorded session to play back (its rig
    /// configuration, object, seed and trial replace `--config`, `--object`,
    /// `--seed` and `--trial`).
    #[arg(long, value_name = "FILE")]
    pub session: Option<PathBuf>,
    /// The live view.
    #[command(flatten)]
    pub live: LiveArgs,
}

/// Arguments of `collect`.
#[derive(Debug, Args)]
pub struct CollectArgs {
    /// The experiment.
    #[command(flatten)]
    pub run: ExperimentArgs,
    /// Number of trials, one session file each.
    #[arg(long, default_value_t = 1)]
    pub trials: u32,
    /// Index of the first trial (trials are numbered from it).
    #[arg(long, default_value_t = 0)]
    pub first_trial: u32,
    /// Directory for the session files (created if missing).
    #[arg(long, default_value = "sessions")]
    pub out: PathBuf,
    /// Also run a vision tracker on the rig's RGB-D camera, when it is the
    /// marker camera too (`--rig hw`, `[hw.camera] kind = "rgbd"`), fed by
    /// `--vision-measurements` (`/estimate/pose/<tracker>` and friends).
    #[arg(long, value_enum)]
    pub vision: Option<VisionArg>,
    /// The vision tracker's options on the camera.
    #[command(flatten)]
    pub camera: CameraVisionArgs,
}

/// Arguments of `record`.
#[derive(Debug, Args)]
pub struct RecordArgs {
    /// The rig whose devices are recorded.
    #[arg(long, value_enum, default_value_t = RigArg::Hw)]
    pub rig: RigArg,
    /// Rig configuration (TOML) naming the devices (`[hw]` table).
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Stop after this many seconds of session time (until Ctrl-C when absent).
    #[arg(long)]
    pub duration: Option<f64>,
    /// Session file to write.
    #[arg(long)]
    pub out: PathBuf,
    /// Replace the session file if it exists (refused otherwise).
    #[arg(long)]
    pub overwrite: bool,
    /// Do not record the camera.
    #[arg(long)]
    pub no_camera: bool,
    /// Object of the simulated devices (simulated or emulated roles only).
    #[arg(long, default_value = "box")]
    pub object: String,
    /// Seed of the simulated devices (simulated or emulated roles only).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// The live view and ROS 2 topics.
    #[command(flatten)]
    pub live: LiveArgs,
}

/// Arguments of `demo`.
#[derive(Debug, Args)]
pub struct DemoArgs {
    /// Directory for the demo's sessions and plots.
    #[arg(long, default_value = "demo-out")]
    pub out: PathBuf,
    /// Duration of the sliding cycles of each trial (s).
    #[arg(long, default_value_t = 60.0)]
    pub duration: f64,
    /// Seed of the simulated rig and of the training.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Sessions to train on.
    #[arg(long, default_value_t = 16)]
    pub train: u32,
    /// Held-out sessions to evaluate on.
    #[arg(long, default_value_t = 4)]
    pub test: u32,
    /// Worker threads (0: every core).
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
}

/// A benchmark of `bench`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum BenchWhat {
    /// Collecting a simulated trial, with and without camera (two cores; target 30x real time with the camera).
    Collect,
    /// One online dEKF step, derivative filter included (one core).
    Dekf,
    /// Training the dEKF on a thesis-sized simulated set (`--threads` cores).
    DekfTraining,
    /// Collecting with and without `--live`, a viewer subscribed to every
    /// channel that never reads (one core; target: at most 10 % slower).
    CollectLive,
    /// Collecting with and without `--ros2`, a DDS subscriber to every
    /// topic that never reads (one core; target: at most 10 % slower).
    CollectRos2,
}

/// Arguments of `bench`.
#[derive(Debug, Args)]
pub struct BenchArgs {
    /// What to measure, comma-separated.
    #[arg(long, value_enum, value_delimiter = ',', default_value = "collect")]
    pub what: Vec<BenchWhat>,
    /// Worker threads of the training benchmark (the 180 s target is for 2
    /// cores); it also trains on 1, 2 and all of the machine's threads and
    /// reports the speed-ups and whether every count trained the same model.
    #[arg(long, default_value_t = 2)]
    pub threads: usize,
    /// Windows per batch of the training benchmark (issue 29 judges the
    /// scaling at the thesis's 32).
    #[arg(long, default_value_t = 32)]
    pub batch: usize,
    /// Windows per part of a batch's gradient in the training benchmark,
    /// comma-separated to compare several (every training of a run in
    /// turn); the first is judged. Default: the largest size (at most
    /// `train`'s default of 16) that gives each of the machine's threads a
    /// part of the batch (16 at batch 32 on 2 cores, 2 on 16 cores).
    #[arg(long, value_delimiter = ',')]
    pub part_windows: Vec<usize>,
    /// Simulated sessions of 60 s the training benchmark trains on (50: the
    /// thesis-sized set, whose target is 180 s; fewer for a quicker look,
    /// the target scaled with them).
    #[arg(long, default_value_t = 50, value_parser = clap::value_parser!(u32).range(1..))]
    pub sessions: u32,
    /// Runs per measurement (the median is reported).
    #[arg(long, default_value_t = 5)]
    pub runs: usize,
    /// Duration of the sliding cycles of the measured trial (s).
    #[arg(long, default_value_t = 60.0)]
    pub duration: f64,
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
}

/// Arguments of `track`.
#[derive(Debug, Args, Clone)]
pub struct TrackArgs {
    /// The experiment.
    #[command(flatten)]
    pub run: ExperimentArgs,
    /// dEKF model file (.safetensors) from `slidetrack train`.
    #[arg(long)]
    pub model: PathBuf,
    /// Trial number (the simulated rig's per-trial jitter derives from it).
    #[arg(long, default_value_t = 0)]
    pub trial: u32,
    /// Session file to write (default: sessions/<object>-s<seed>-t<trial>-track.mcap).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Also run a vision tracker beside the dEKF (`/estimate/pose/<tracker>`
    /// and friends). On the simulated rig it tracks the rendered in-hand
    /// RGB-D scene, fed by an imitation of a slow network (5 fps, 200 ms
    /// late); on a hardware rig the `[rgbd]` camera of `--config`, fed by
    /// `--vision-measurements`, on its own thread, recording the frames
    /// (`/rgbd/*`) into the same session.
    #[arg(long, value_enum)]
    pub vision: Option<VisionArg>,
    /// With `--vision` on the simulated rig: also record the rendered
    /// colour, depth and masks (about 1 MB per frame).
    #[arg(long, requires = "vision")]
    pub record_rgbd: bool,
    /// The vision tracker's options on a camera.
    #[command(flatten)]
    pub camera: CameraVisionArgs,
}

/// The options of a `--vision` tracker on a hardware rig's RGB-D camera
/// (`track`, `collect`).
#[derive(Debug, Args, Clone)]
pub struct CameraVisionArgs {
    /// With `--vision` on a hardware rig: the object model the tracker fits
    /// (.obj, .ply or .xyz in metres, a simulated object's name such as
    /// `cracker_box`, or `sim` for the object of a recording standing in
    /// for the camera).
    #[arg(long, requires = "vision")]
    pub vision_model: Option<String>,
    /// Scale of `--vision-model`'s coordinates to metres (0.001 for mm).
    #[arg(long, default_value_t = 1.0)]
    pub vision_model_scale: f64,
    /// With `--vision` on a hardware rig: where masks and poses come from.
    #[arg(long, value_enum, default_value_t = CameraMeasurementsArg::Aruco)]
    pub vision_measurements: CameraMeasurementsArg,
    /// The marker on the object, for `--vision-measurements aruco` (as
    /// `vision track --aruco-config`).
    #[arg(long)]
    pub aruco_config: Option<PathBuf>,
    /// The socket of `--vision-measurements external`.
    #[command(flatten)]
    pub external: super::vision::ExternalArgs,
    /// With `--vision maskukf` on a hardware rig: start again at a pose
    /// measurement more than CM centimetres or DEG degrees from the estimate
    /// (as `vision track --pose-reset`).
    #[arg(long, value_name = "CM,DEG", value_parser = super::vision::parse_pose_reset, requires = "vision")]
    pub pose_reset: Option<PoseReset>,
}

/// Masks and poses of a vision tracker on a real camera.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum CameraMeasurementsArg {
    /// Poses from an ArUco marker fixed to the object, masks rendered from
    /// the model at them (`--aruco-config`).
    Aruco,
    /// Masks and poses from another process over a local socket
    /// (`--listen`; protocol in docs/protocols.md).
    External,
}

/// A vision tracker of `--vision`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum VisionArg {
    /// MaskUKF (thesis Chapter 4).
    Maskukf,
    /// ROFT (thesis Chapter 5).
    Roft,
}

impl From<VisionArg> for TrackerKind {
    fn from(v: VisionArg) -> TrackerKind {
        match v {
            VisionArg::Maskukf => TrackerKind::MaskUkf,
            VisionArg::Roft => TrackerKind::Roft,
        }
    }
}

impl From<CameraMeasurementsArg> for Measurements {
    fn from(arg: CameraMeasurementsArg) -> Measurements {
        match arg {
            CameraMeasurementsArg::Aruco => Measurements::Aruco,
            CameraMeasurementsArg::External => Measurements::External,
        }
    }
}

impl CameraVisionArgs {
    /// The options of the `--vision` tracker `kind` on a camera.
    pub fn options(&self, kind: VisionArg) -> CameraVisionOptions<'_> {
        CameraVisionOptions {
            kind: kind.into(),
            model: self.vision_model.as_deref(),
            model_scale: self.vision_model_scale,
            measurements: self.vision_measurements.into(),
            aruco_config: self.aruco_config.as_deref(),
            external: self.external.config(),
            pose_reset: self.pose_reset,
        }
    }
}
