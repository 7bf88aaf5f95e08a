//! Command-line arguments.

use std::path::PathBuf;

use clap::{Args, Parser, Subcommand, ValueEnum};

/// Controlled-sliding grasp experiments with tactile sensors and cameras:
/// collect sessions on the simulated or the real rig, inspect and plot them.
#[derive(Debug, Parser)]
#[command(name = "slidetrack", version, about, long_about = None, propagate_version = true)]
pub struct Cli {
    /// More diagnostics on stderr (-v info, -vv debug).
    #[arg(short, long, global = true, action = clap::ArgAction::Count)]
    pub verbose: u8,
    /// Only errors on stderr, no progress bars.
    #[arg(short, long, global = true)]
    pub quiet: bool,
    /// The command to run.
    #[command(subcommand)]
    pub command: Command,
}

/// The commands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Run controlled-sliding trials and record one session (.mcap) per trial.
    Collect(CollectArgs),
    /// Show a session's channels, message counts, rates, duration and metadata.
    Info(InfoArgs),
    /// Write one channel of a session as CSV to stdout.
    Export(ExportArgs),
    /// Plot a session: grasp strength, tactile traces, marker position.
    Plot(PlotArgs),
    /// Collect a few simulated trials and report what they hold.
    Demo(DemoArgs),
    /// Measure collection speed against the targets.
    Bench(BenchArgs),
    /// List the built-in objects of the simulated rig.
    Objects,
    /// Vision trackers (MaskUKF, ROFT): simulate RGB-D sessions, track, evaluate.
    Vision(crate::commands::vision::VisionArgs),
    /// Build the ground truth of sessions from the ArUco marker (RTS smoother).
    Label(LabelArgs),
    /// Calibrate a camera's intrinsics from views of a chessboard, ChArUco board or circle grid.
    Calibrate(CalibrateArgs),
    /// ArUco marker tools: detect markers (and their poses) in an image.
    Aruco(ArucoArgs),
    /// List the cameras (with their formats), serial ports and CAN interfaces present.
    Devices(DevicesArgs),
    /// Train a dEKF model on labelled sessions (BPTT, Sec. 6.2.4).
    Train(crate::commands::train::TrainArgs),
    /// Run a dEKF model over a session and write a copy with its estimates.
    Replay(crate::commands::replay::ReplayArgs),
    /// Score a dEKF model on labelled sessions (RMSE and max errors, Table 6.1).
    Eval(crate::commands::eval::EvalArgs),
    /// Run the experiment with the dEKF (and the marker filter) live, recorded to a session.
    Track(crate::commands::track::TrackArgs),
    /// The experiments of thesis Sec. 6.3 on the simulated rig: Tables 6.1-6.4.
    Study(crate::commands::study::StudyArgs),
    /// Turn captured tactile traffic (candump log, raw serial bytes) into a session.
    Decode(DecodeArgs),
}

/// Arguments of `devices`.
#[derive(Debug, Args)]
pub struct DevicesArgs {
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
}

/// Arguments of `decode`.
#[derive(Debug, Args)]
#[command(group(clap::ArgGroup::new("capture").required(true).args(["can_log", "serial_capture"])))]
pub struct DecodeArgs {
    /// A can-utils `candump -l` log of a uSkin board (XELA layout).
    #[arg(long, value_name = "FILE")]
    pub can_log: Option<PathBuf>,
    /// Raw bytes captured from a uSkin serial port (e.g. `cat /dev/ttyACM0 > capture.bin`).
    #[arg(long, value_name = "FILE")]
    pub serial_capture: Option<PathBuf>,
    /// Session file to write (.mcap).
    #[arg(long)]
    pub out: PathBuf,
    /// Rig configuration whose [hw.tactile] table describes the device
    /// (ids, taxel counts, finger map); the defaults of `kind` otherwise.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Scan rate of a serial capture (Hz), which sets its log times; the
    /// configuration's `rate_hz` otherwise.
    #[arg(long)]
    pub rate: Option<f64>,
    /// Taxels on the CAN board (overrides the configuration).
    #[arg(long)]
    pub taxels: Option<u16>,
    /// Only frames of this interface of the CAN log (all by default).
    #[arg(long)]
    pub interface: Option<String>,
    /// Replace the output file if it exists.
    #[arg(long)]
    pub overwrite: bool,
}

/// Which rig runs the trial.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum RigKind {
    /// The simulated rig (physics model of the hand, object and sensors).
    Sim,
    /// The real rig, with the devices of the rig configuration.
    Hw,
}

/// The experiment to run: rig, object, duration and how (`collect`, `track`).
#[derive(Debug, Args, Clone)]
pub struct ExperimentArgs {
    /// The rig to run on.
    #[arg(long, value_enum, default_value_t = RigKind::Sim)]
    pub rig: RigKind,
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
}

/// Arguments of `info`.
#[derive(Debug, Args)]
pub struct InfoArgs {
    /// Session file (.mcap).
    pub file: PathBuf,
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
    /// Read a truncated file (writer killed) up to its last complete chunk.
    #[arg(long)]
    pub recover: bool,
}

/// Arguments of `export`.
#[derive(Debug, Args)]
pub struct ExportArgs {
    /// Session file (.mcap).
    pub file: PathBuf,
    /// Channel (topic) to export, e.g. /tactile/raw.
    #[arg(long)]
    pub channel: String,
    /// Read a truncated file (writer killed) up to its last complete chunk.
    #[arg(long)]
    pub recover: bool,
}

/// What `plot` draws.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum PlotKind {
    /// Grasp strength, tactile traces and marker position, stacked.
    Overview,
    /// Desired vs achieved grasp strength per finger (thesis Fig. 6.4).
    Grasp,
    /// Baseline-subtracted tactile channels per finger and marker position (Fig. 6.8).
    Tactile,
    /// Marker position, filtered and smoothed ground truth, position and velocity (Fig. 6.5).
    GroundTruth,
}

/// Arguments of `plot`.
#[derive(Debug, Args)]
pub struct PlotArgs {
    /// Session file (.mcap).
    pub file: PathBuf,
    /// Output image (.png).
    #[arg(long)]
    pub out: PathBuf,
    /// What to plot.
    #[arg(long, value_enum, default_value_t = PlotKind::Overview)]
    pub what: PlotKind,
    /// Read a truncated file (writer killed) up to its last complete chunk.
    #[arg(long)]
    pub recover: bool,
}

/// Where `label` takes the marker positions along the sliding axis from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum AxisArg {
    /// `position_on_axis_m` as recorded online with the rig's geometry.
    Recorded,
    /// Recompute from `position_in_camera_m` with the camera placement and
    /// sliding axis of the rig configuration stored in the session.
    Config,
    /// Recompute along the principal direction of the marker track.
    Estimate,
}

/// Arguments of `label`.
#[derive(Debug, Args)]
pub struct LabelArgs {
    /// Session files (.mcap) to label; each is rewritten in place, atomically.
    #[arg(required = true)]
    pub files: Vec<PathBuf>,
    /// Source of the marker positions along the sliding axis.
    #[arg(long, value_enum, default_value_t = AxisArg::Recorded)]
    pub axis: AxisArg,
    /// Start from the thesis's parameters (Q = diag(0.01, 0.01) per 1/30 s
    /// step, R = 10, read in cm; no gate) instead of the defaults.
    #[arg(long)]
    pub thesis: bool,
    /// Spectral density of the position random walk q_p (m^2/s); Q = diag(q_p, q_v) * dt.
    #[arg(long, value_name = "M2_PER_S")]
    pub q_position: Option<f64>,
    /// Spectral density of the velocity random walk q_v (m^2/s^3).
    #[arg(long, value_name = "M2_PER_S3")]
    pub q_velocity: Option<f64>,
    /// Variance of a marker position R (m^2).
    #[arg(long, value_name = "M2")]
    pub r: Option<f64>,
    /// Reject marker positions whose squared Mahalanobis distance exceeds this.
    #[arg(long, value_name = "D2", conflicts_with = "no_gate")]
    pub gate: Option<f64>,
    /// Use every marker position (no outlier gate).
    #[arg(long)]
    pub no_gate: bool,
    /// Compute and report only; leave the files as they are.
    #[arg(long)]
    pub dry_run: bool,
    /// Label a truncated file (writer killed) from its complete chunks; the result is a complete file.
    #[arg(long)]
    pub recover: bool,
    /// Print a JSON summary per file instead of text.
    #[arg(long)]
    pub json: bool,
}

/// Arguments of `calibrate`.
#[derive(Debug, Args)]
pub struct CalibrateArgs {
    /// What to calibrate.
    #[command(subcommand)]
    pub what: CalibrateCommand,
}

/// The calibrations.
#[derive(Debug, Subcommand)]
pub enum CalibrateCommand {
    /// Camera intrinsics (pinhole + plumb-bob distortion) from pattern views:
    /// image files, a V4L2 camera, or the simulated camera.
    Camera(CalibrateCameraArgs),
}

/// Output format of the camera calibration.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum CalibrationFormatArg {
    /// ROS camera_info YAML.
    Ros,
    /// OpenCV FileStorage YAML.
    Opencv,
}

/// Arguments of `calibrate camera`.
#[derive(Debug, Args)]
#[command(group(clap::ArgGroup::new("source").required(true).args(["images", "device", "sim"])))]
pub struct CalibrateCameraArgs {
    /// Image files or glob patterns (quote them: 'calib/*.jpg').
    #[arg(long, num_args = 1.., value_name = "GLOB")]
    pub images: Vec<String>,
    /// Capture live from this V4L2 camera (no preview window).
    #[arg(long, value_name = "DEVICE")]
    pub device: Option<PathBuf>,
    /// Capture live from the simulated camera looking at a rendered chessboard.
    #[arg(long)]
    pub sim: bool,
    /// Rig configuration whose [camera] the simulated camera uses (with --sim).
    #[arg(long, requires = "sim")]
    pub config: Option<PathBuf>,
    /// The pattern: chessboard:COLSxROWS:SQUARE_M (inner corners),
    /// charuco:SQUARESXxSQUARESY:SQUARE_M:MARKER_M[:DICT], circles-asym:COLSxROWS:SPACING_M.
    #[arg(long)]
    pub pattern: String,
    /// Views to capture in live mode.
    #[arg(long, default_value_t = 20)]
    pub views: usize,
    /// Frame width to stream from --device (px).
    #[arg(long, default_value_t = 640)]
    pub width: u32,
    /// Frame height to stream from --device (px).
    #[arg(long, default_value_t = 480)]
    pub height: u32,
    /// Give up live capture after this many seconds.
    #[arg(long, default_value_t = 300.0)]
    pub timeout: f64,
    /// Live mode: also save each kept view as DIR/view-NN.png (lossless), to
    /// calibrate again from the files with --images.
    #[arg(long, value_name = "DIR", conflicts_with = "images")]
    pub save_views: Option<PathBuf>,
    /// Output file.
    #[arg(long, default_value = "camera.yaml")]
    pub out: PathBuf,
    /// Output format.
    #[arg(long, value_enum, default_value_t = CalibrationFormatArg::Ros)]
    pub format: CalibrationFormatArg,
    /// Camera name written in the file.
    #[arg(long, default_value = "camera")]
    pub camera_name: String,
    /// Keep fx = fy.
    #[arg(long)]
    pub fix_aspect_ratio: bool,
    /// Keep the tangential distortion at zero.
    #[arg(long)]
    pub zero_tangent: bool,
    /// Keep k3 at zero.
    #[arg(long)]
    pub fix_k3: bool,
    /// Print the result as JSON.
    #[arg(long)]
    pub json: bool,
}

/// Arguments of `aruco`.
#[derive(Debug, Args)]
pub struct ArucoArgs {
    /// The tool.
    #[command(subcommand)]
    pub what: ArucoCommand,
}

/// The marker tools.
#[derive(Debug, Subcommand)]
pub enum ArucoCommand {
    /// Detect markers in an image; with intrinsics and a marker size, their poses too.
    Detect(ArucoDetectArgs),
}

/// OpenCV's corner refinement methods.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum RefineArg {
    /// The polygon's corners (OpenCV's default).
    None,
    /// cornerSubPix.
    Subpix,
    /// Lines fitted to the contour.
    Contour,
    /// AprilTag's quad fit.
    Apriltag,
}

/// Arguments of `aruco detect`.
#[derive(Debug, Args)]
pub struct ArucoDetectArgs {
    /// Image file.
    pub image: PathBuf,
    /// OpenCV dictionary name (DICT_6X6_250, DICT_APRILTAG_36h11, ...) or an OpenCV dictionary file.
    #[arg(long, default_value = "DICT_6X6_250")]
    pub dict: String,
    /// Camera calibration (ROS camera_info or OpenCV YAML), for poses.
    #[arg(long, requires = "marker_size")]
    pub camera: Option<PathBuf>,
    /// Side of the markers' black square (m), for poses.
    #[arg(long, requires = "camera")]
    pub marker_size: Option<f64>,
    /// OpenCV detector parameters file (detector_params.yml).
    #[arg(long)]
    pub params: Option<PathBuf>,
    /// Corner refinement.
    #[arg(long, value_enum, default_value_t = RefineArg::None)]
    pub refine: RefineArg,
    /// Print JSON.
    #[arg(long)]
    pub json: bool,
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
    /// Collecting a simulated trial, with and without camera (one core).
    Collect,
    /// One online dEKF step, derivative filter included (one core).
    Dekf,
    /// Training the dEKF on a thesis-sized simulated set (`--threads` cores).
    DekfTraining,
}

/// Arguments of `bench`.
#[derive(Debug, Args)]
pub struct BenchArgs {
    /// What to measure, comma-separated.
    #[arg(long, value_enum, value_delimiter = ',', default_value = "collect")]
    pub what: Vec<BenchWhat>,
    /// Worker threads of the training benchmark (the target is for 2 cores).
    #[arg(long, default_value_t = 2)]
    pub threads: usize,
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn collect_parses_the_documented_example() {
        let cli = Cli::try_parse_from([
            "slidetrack",
            "collect",
            "--rig",
            "sim",
            "--object",
            "box",
            "--trials",
            "10",
            "--duration",
            "60",
            "--seed",
            "1",
            "--out",
            "DIR",
        ])
        .unwrap();
        let Command::Collect(a) = cli.command else { panic!("not collect") };
        assert_eq!(
            (a.run.rig, a.run.object.as_str(), a.trials, a.run.duration, a.run.seed),
            (RigKind::Sim, "box", 10, 60.0, 1)
        );
        assert_eq!(a.out, PathBuf::from("DIR"));
        assert!(!a.run.no_camera);
    }

    #[test]
    fn unknown_rig_is_a_parse_error() {
        assert!(Cli::try_parse_from(["slidetrack", "collect", "--rig", "moon"]).is_err());
    }

    #[test]
    fn decode_needs_exactly_one_capture() {
        let parse = |args: &[&str]| Cli::try_parse_from([&["slidetrack", "decode"], args].concat());
        assert!(parse(&["--out", "x.mcap"]).is_err());
        assert!(parse(&["--can-log", "a.log", "--serial-capture", "b.bin", "--out", "x.mcap"]).is_err());
        let cli = parse(&["--can-log", "a.log", "--out", "x.mcap", "--taxels", "16"]).unwrap();
        let Command::Decode(a) = cli.command else { panic!("not decode") };
        assert_eq!((a.can_log, a.taxels), (Some(PathBuf::from("a.log")), Some(16)));
        assert!(Cli::try_parse_from(["slidetrack", "devices", "--json"]).is_ok());
    }

    #[test]
    fn label_calibrate_and_aruco_parse() {
        let cli =
            Cli::try_parse_from(["slidetrack", "label", "a.mcap", "b.mcap", "--axis", "estimate", "--json"])
                .unwrap();
        let Command::Label(a) = cli.command else { panic!("not label") };
        assert_eq!((a.files.len(), a.axis, a.json), (2, AxisArg::Estimate, true));
        assert!(Cli::try_parse_from(["slidetrack", "label"]).is_err());
        assert!(Cli::try_parse_from(["slidetrack", "label", "a.mcap", "--gate", "9", "--no-gate"]).is_err());
        let cli = Cli::try_parse_from([
            "slidetrack",
            "calibrate",
            "camera",
            "--images",
            "a/*.jpg",
            "b.png",
            "--pattern",
            "chessboard:9x6:0.025",
            "--format",
            "opencv",
        ])
        .unwrap();
        let Command::Calibrate(CalibrateArgs { what: CalibrateCommand::Camera(c) }) = cli.command else {
            panic!("not calibrate camera")
        };
        assert_eq!((c.images.len(), c.format), (2, CalibrationFormatArg::Opencv));
        assert!(
            Cli::try_parse_from(["slidetrack", "calibrate", "camera", "--pattern", "chessboard:9x6:0.025"])
                .is_err()
        );
        assert!(
            Cli::try_parse_from(["slidetrack", "aruco", "detect", "x.png", "--camera", "c.yaml"]).is_err()
        );
        let cli = Cli::try_parse_from([
            "slidetrack",
            "aruco",
            "detect",
            "x.png",
            "--camera",
            "c.yaml",
            "--marker-size",
            "0.03",
        ]);
        assert!(cli.is_ok());
        let cli =
            Cli::try_parse_from(["slidetrack", "plot", "x.mcap", "--out", "g.png", "--what", "ground-truth"])
                .unwrap();
        let Command::Plot(p) = cli.command else { panic!("not plot") };
        assert_eq!(p.what, PlotKind::GroundTruth);
    }
    #[test]
    fn export_needs_a_channel() {
        assert!(Cli::try_parse_from(["slidetrack", "export", "x.mcap"]).is_err());
        assert!(Cli::try_parse_from(["slidetrack", "export", "x.mcap", "--channel", "/tactile/raw"]).is_ok());
    }
}
