//! Arguments of `calibrate` and `aruco`.

use std::path::PathBuf;

use clap::{Args, Subcommand, ValueEnum};

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
    /// Tactile counts to newtons: a map per taxel (per axis, with
    /// cross-talk) fitted on sessions with reference forces, or applied to
    /// a session (`--apply`).
    Tactile(super::tactile::CalibrateTactileArgs),
    /// The camera's pose in the hand frame from a marker fixed to the hand
    /// (`[hand_target]` in the rig TOML); prints a `[camera] placement` line.
    Hand(CalibrateHandArgs),
}

/// Where `calibrate hand` takes its frames from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum HandRigArg {
    /// The simulated camera rendering the hand's target.
    Sim,
}

/// Arguments of `calibrate hand`.
#[derive(Debug, Args)]
pub struct CalibrateHandArgs {
    /// The rig whose camera sees the hand's target (without --session).
    #[arg(long, value_enum, default_value_t = HandRigArg::Sim)]
    pub rig: HandRigArg,
    /// Take the frames from this recorded session (MCAP) instead: its
    /// /camera/image (else /rgbd/color) frames, with its camera calibration
    /// (else the rig config's camera).
    #[arg(long, conflicts_with_all = ["rig", "seed"])]
    pub session: Option<PathBuf>,
    /// Rig configuration (TOML) with [camera] and [hand_target].
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Frames to take: rendered by the simulated camera (default 30), or at
    /// most this many of the session's, evenly spread (default all).
    #[arg(long)]
    pub frames: Option<usize>,
    /// Seed of the simulated camera's noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Also write `[camera] placement = ...` (TOML) to this file.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Print the result as JSON.
    #[arg(long)]
    pub json: bool,
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
    /// Detect markers in an image; with intrinsics and a marker size, their
    /// poses too; with intrinsics and a board, the board's pose.
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
#[command(group(clap::ArgGroup::new("target").args(["marker_size", "board"])))]
pub struct ArucoDetectArgs {
    /// Image file.
    pub image: PathBuf,
    /// OpenCV dictionary name (DICT_6X6_250, DICT_APRILTAG_36h11, ...) or an OpenCV dictionary file.
    #[arg(long, default_value = "DICT_6X6_250")]
    pub dict: String,
    /// Camera calibration (ROS camera_info or OpenCV YAML), for poses.
    #[arg(long, requires = "target")]
    pub camera: Option<PathBuf>,
    /// Side of the markers' black square (m), for poses.
    #[arg(long, requires = "camera")]
    pub marker_size: Option<f64>,
    /// A board's layout (TOML, the keys of a rig's [marker.board]: kind =
    /// "grid" or "charuco" and its sizes), for the board's pose from all its
    /// markers or ChArUco corners.
    #[arg(long, requires = "camera")]
    pub board: Option<PathBuf>,
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
