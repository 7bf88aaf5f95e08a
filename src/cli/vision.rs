//! Arguments of `vision` and its subcommands.

use std::path::PathBuf;
use std::time::Duration;

use clap::{Args, Subcommand, ValueEnum};
use slidetrack_experiment::vision::input::InputOptions;
use slidetrack_experiment::vision::{ExternalConfig, Measurements, PoseReset, TrackerKind, TrackerStart};

/// Arguments of `vision`.
#[derive(Debug, Args)]
pub struct VisionArgs {
    /// What to do.
    #[command(subcommand)]
    pub command: VisionCommand,
}

/// The vision commands.
#[derive(Debug, Subcommand)]
pub enum VisionCommand {
    /// Record a simulated RGB-D session of a fast-moving object, with the true
    /// pose, velocity and masks, and the imitated slow network's masks and poses.
    Simulate(VisionSimulateArgs),
    /// Track an object in a session or a YCB-Video-style directory and write
    /// the estimates to a session.
    Track(VisionTrackArgs),
    /// Score the trackers on simulated fast sequences (or on inputs with
    /// ground truth): ADD-AUC, ADI-AUC, RMSEs; --ablation for Table 5.6.
    Eval(VisionEvalArgs),
}

/// The trackers on the command line.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum TrackerArg {
    /// MaskUKF: segmentation + depth, sequential UKF (Chapter 4).
    Maskukf,
    /// ROFT: optical flow + delayed masks and poses (Chapter 5).
    Roft,
}

/// Where masks and poses come from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum MeasurementsArg {
    /// The input's own: a session's /vision/mask and /vision/pose, or the
    /// label masks of a YCB-Video directory (every frame, no delay).
    Input,
    /// The imitated slow network (5 fps, 200 ms late) from the input's truth.
    Network,
    /// The input's ground truth, every frame, without delay.
    Truth,
    /// Poses from an ArUco marker fixed to the object, masks rendered from
    /// the model at them (--aruco-config).
    Aruco,
    /// Masks and poses from another process over a local socket
    /// (--listen; protocol in docs/protocols.md).
    External,
}

/// How a tracker starts.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum InitArg {
    /// From the first pose measurement that arrives.
    Measurement,
    /// From the input's true pose of the first frame.
    Truth,
    /// From the true pose of the first frame moved 5 cm along each axis and
    /// turned 10 degrees on each Euler angle (thesis Sec. 4.2.3).
    Perturbed,
}

/// Arguments of `vision simulate`.
#[derive(Debug, Args)]
pub struct VisionSimulateArgs {
    /// Object: cracker_box, sugar_box, soup_can, mustard_bottle, gelatin_box, meat_can.
    #[arg(long, default_value = "cracker_box")]
    pub object: String,
    /// Length of the sequence (s), at 30 Hz.
    #[arg(long, default_value_t = 10.0)]
    pub duration: f64,
    /// Seed of the motion, the noise and the network.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Peak linear speed (m/s).
    #[arg(long, default_value_t = 0.6)]
    pub max_speed: f64,
    /// Peak angular speed (deg/s).
    #[arg(long, default_value_t = 270.0)]
    pub max_angular_speed: f64,
    /// Print an ArUco marker, DICTIONARY:ID (for example DICT_4X4_50:0), on
    /// the object's face seen most in the first frame, and write the
    /// matching --aruco-config next to the session (OUT.aruco.toml).
    #[arg(long)]
    pub marker: Option<String>,
    /// Side of the printed marker's black square (m).
    #[arg(long, default_value_t = 0.05)]
    pub marker_size: f64,
    /// Session file to write.
    #[arg(long)]
    pub out: PathBuf,
    /// Replace the file if it exists.
    #[arg(long)]
    pub overwrite: bool,
}

/// Arguments of `vision track`.
#[derive(Debug, Args)]
pub struct VisionTrackArgs {
    /// The tracker.
    #[arg(long, value_enum)]
    pub tracker: TrackerArg,
    /// An RGB-D session (.mcap) or a directory of YCB-Video-style frames
    /// (NNNNNN-color.png, -depth.png, -label.png, -meta.mat).
    #[arg(long, required_unless_present = "live", conflicts_with = "live")]
    pub input: Option<PathBuf>,
    /// Object model: .obj, .ply or .xyz (metres), or `sim` for the object of
    /// a simulated session.
    #[arg(long)]
    pub model: String,
    /// Scale of the model's coordinates to metres (0.001 for millimetres).
    #[arg(long, default_value_t = 1.0)]
    pub model_scale: f64,
    /// YCB-Video class to track in a directory: its name (009_gelatin_box)
    /// or 1-based index; default: the model's directory name.
    #[arg(long)]
    pub object: Option<String>,
    /// Where masks and poses come from.
    #[arg(long, value_enum, default_value_t = MeasurementsArg::Input)]
    pub measurements: MeasurementsArg,
    /// How the tracker starts.
    #[arg(long, value_enum, default_value_t = InitArg::Measurement)]
    pub init: InitArg,
    /// The marker on the object, for --measurements aruco: a TOML file
    /// (dictionary, marker_id, marker_size_m, marker_from_object, ...; see
    /// docs/vision.md).
    #[arg(long, required_if_eq("measurements", "aruco"))]
    pub aruco_config: Option<PathBuf>,
    #[command(flatten)]
    pub external: ExternalArgs,
    /// Session file for the estimates (/estimate/pose|transform|velocity/<tracker>).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Replace the output file if it exists.
    #[arg(long)]
    pub overwrite: bool,
    /// Read a truncated input session up to its last complete chunk.
    #[arg(long)]
    pub recover: bool,
    /// Print the summary as JSON.
    #[arg(long)]
    pub json: bool,
    /// Track live on the `[rgbd]` camera of --rig (V4L2 colour and depth
    /// nodes, or a recording standing in for them), until Ctrl-C or
    /// --duration; with --out the RGB-D frames are recorded too.
    #[arg(long, requires = "rig")]
    pub live: bool,
    /// Rig TOML with the `[rgbd]` table, for --live.
    #[arg(long, requires = "live")]
    pub rig: Option<PathBuf>,
    /// Stop a --live run after this long (s); default: Ctrl-C (or the end
    /// of a recording).
    #[arg(long, requires = "live")]
    pub duration: Option<f64>,
    /// MaskUKF: start again at a pose measurement more than CM centimetres
    /// or DEG degrees from the estimate (for example `3,20`); for a live
    /// camera whose skipped frames can lose the object's rotation. Off by
    /// default: the thesis's MaskUKF uses masks only.
    #[arg(long, value_name = "CM,DEG", value_parser = parse_pose_reset)]
    pub pose_reset: Option<PoseReset>,
}

/// `--pose-reset CM,DEG`.
pub fn parse_pose_reset(text: &str) -> Result<PoseReset, String> {
    let numbers: Vec<f64> = text
        .split(',')
        .map(|x| x.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|e| format!("{text:?}: {e} (expected CM,DEG, for example 3,20)"))?;
    match numbers[..] {
        [cm, deg] if cm > 0.0 && deg > 0.0 && cm.is_finite() && deg.is_finite() => {
            Ok(PoseReset { position_m: cm / 100.0, rotation_deg: deg })
        }
        _ => Err(format!("{text:?}: expected two positive numbers CM,DEG, for example 3,20")),
    }
}

/// The socket of `--measurements external`.
#[derive(Clone, Debug, Args)]
pub struct ExternalArgs {
    /// Address the external source listens on (localhost TCP).
    #[arg(long, default_value = "127.0.0.1:7450")]
    pub listen: String,
    /// With a client connected, wait up to this long (ms) at each frame for
    /// its result (recorded inputs); 0: never wait (live cameras).
    #[arg(long, default_value_t = 1000)]
    pub external_wait_ms: u64,
    /// Before the first frame, wait up to this long (ms) for a client to
    /// connect; 0: start at once.
    #[arg(long, default_value_t = 0)]
    pub external_wait_client_ms: u64,
    /// Results older than this (ms) when they arrive are dropped.
    #[arg(long, default_value_t = 1000)]
    pub external_max_age_ms: u64,
    /// Send each frame's colour (JPEG) and depth (PNG) to the client.
    #[arg(long)]
    pub external_send_images: bool,
}

/// Arguments of `vision eval`.
#[derive(Debug, Args)]
pub struct VisionEvalArgs {
    /// Simulated sequences per object.
    #[arg(long, default_value_t = 1)]
    pub sequences: usize,
    /// Objects of the simulated sequences (comma-separated); default all six.
    #[arg(long, value_delimiter = ',')]
    pub objects: Vec<String>,
    /// Length of each simulated sequence (s).
    #[arg(long, default_value_t = 8.0)]
    pub duration: f64,
    /// Seed of the first sequence.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Run the ROFT variants of Table 5.6 (with and without each component).
    #[arg(long)]
    pub ablation: bool,
    /// Instead of simulated sequences: inputs with ground truth (sessions
    /// with /sim/object, or YCB-Video-style directories), tracked with the
    /// settings of `vision track`.
    #[arg(long, num_args = 1..)]
    pub input: Vec<PathBuf>,
    /// Tracker for --input.
    #[arg(long, value_enum, default_value_t = TrackerArg::Roft)]
    pub tracker: TrackerArg,
    /// Object model for --input (as in `vision track`).
    #[arg(long)]
    pub model: Option<String>,
    /// YCB-Video class for directory inputs.
    #[arg(long)]
    pub object: Option<String>,
    /// Where masks and poses come from, for --input.
    #[arg(long, value_enum, default_value_t = MeasurementsArg::Input)]
    pub measurements: MeasurementsArg,
    /// How the tracker starts, for --input.
    #[arg(long, value_enum, default_value_t = InitArg::Measurement)]
    pub init: InitArg,
    /// Print JSON instead of a table.
    #[arg(long)]
    pub json: bool,
}

impl TrackerArg {
    /// The library's kind.
    pub fn kind(self) -> TrackerKind {
        match self {
            TrackerArg::Maskukf => TrackerKind::MaskUkf,
            TrackerArg::Roft => TrackerKind::Roft,
        }
    }
}

impl From<MeasurementsArg> for Measurements {
    fn from(arg: MeasurementsArg) -> Measurements {
        match arg {
            MeasurementsArg::Input => Measurements::Input,
            MeasurementsArg::Network => Measurements::Network,
            MeasurementsArg::Truth => Measurements::Truth,
            MeasurementsArg::Aruco => Measurements::Aruco,
            MeasurementsArg::External => Measurements::External,
        }
    }
}

impl From<InitArg> for TrackerStart {
    fn from(arg: InitArg) -> TrackerStart {
        match arg {
            InitArg::Measurement => TrackerStart::Measurement,
            InitArg::Truth => TrackerStart::Truth,
            InitArg::Perturbed => TrackerStart::Perturbed,
        }
    }
}

impl ExternalArgs {
    /// The external source's settings.
    pub fn config(&self) -> ExternalConfig {
        ExternalConfig {
            listen: self.listen.clone(),
            wait_for_result: (self.external_wait_ms > 0)
                .then(|| Duration::from_millis(self.external_wait_ms)),
            wait_for_client: (self.external_wait_client_ms > 0)
                .then(|| Duration::from_millis(self.external_wait_client_ms)),
            max_age_ns: self.external_max_age_ms.saturating_mul(1_000_000),
            send_images: self.external_send_images,
        }
    }
}

impl VisionTrackArgs {
    /// The model, measurements and start of the tracker.
    pub fn input_options(&self) -> InputOptions<'_> {
        InputOptions {
            model: &self.model,
            model_scale: self.model_scale,
            object: self.object.as_deref(),
            measurements: self.measurements.into(),
            init: self.init.into(),
            recover: self.recover,
            aruco_config: self.aruco_config.as_deref(),
            external: Some(self.external.config()),
        }
    }
}
