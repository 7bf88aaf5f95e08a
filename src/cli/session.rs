//! Arguments of the commands that read, plot, label and decode sessions, and
//! of `devices`.

use std::path::PathBuf;

use clap::{Args, ValueEnum};

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
    /// Channel (topic) to export as CSV on stdout, e.g. /tactile/raw.
    #[arg(long, required_unless_present = "ros2_bag", conflicts_with = "ros2_bag")]
    pub channel: Option<String>,
    /// Write the session as a ROS 2 bag (MCAP, CDR, ros2msg schemas) to this
    /// file instead (see docs/session-format.md, "As a ROS 2 bag").
    #[arg(long, value_name = "OUT.mcap")]
    pub ros2_bag: Option<PathBuf>,
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

/// The ground-truth channels `label` writes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum SlotArg {
    /// `/ground_truth/sliding` and `/ground_truth/measurements`.
    Default,
    /// `/ground_truth/thesis/sliding` and `/ground_truth/thesis/measurements`.
    Thesis,
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
    /// After N marker positions in a row rejected by the gate, open it
    /// until N in a row fall inside again, so that an object that moved
    /// faster than the model allows (a fall) is followed again instead of
    /// the filter coasting away for the rest of the session (0: never, the
    /// default). Not recorded in old sessions, which never re-acquire.
    #[arg(long, value_name = "N", default_value_t = 0, conflicts_with = "no_gate")]
    pub reacquire_after: u32,
    /// Estimate q_p, q_v and R from each session's marker positions
    /// (maximum likelihood, starting from the values above) and label with
    /// those; they are recorded in the ground-truth channels' metadata.
    /// Tunes with the innovation gate (the default one unless --gate says).
    #[arg(long, conflicts_with = "no_gate")]
    pub tune: bool,
    /// With --tune: one set of parameters for all the files (one rig and
    /// marker), maximising the summed likelihood of their marker positions,
    /// instead of one per file; steadier where a session holds little
    /// motion or few marker positions. Every file is read before any is written.
    #[arg(long, requires = "tune")]
    pub jointly: bool,
    /// Where to write the ground truth: `default` on `/ground_truth/sliding`
    /// and `/ground_truth/measurements` (what `train`, `eval` and the plots
    /// read), or `thesis` on `/ground_truth/thesis/...` (what `--truth
    /// thesis-ground-truth` and `study --protocol thesis` read). Labelling
    /// replaces the channels of its slot only: the other slot's stay.
    #[arg(long, value_enum, default_value_t = SlotArg::Default)]
    pub slot: SlotArg,
    /// Compute and report only; leave the files as they are.
    #[arg(long)]
    pub dry_run: bool,
    /// Label a truncated file (writer killed) from its complete chunks; the result is a complete file.
    #[arg(long)]
    pub recover: bool,
    /// Print a JSON summary per file instead of text.
    #[arg(long)]
    pub json: bool,
    /// Do not label the motion in the hand (`/ground_truth/pose` and
    /// `/ground_truth/planar`, written by default when the marker
    /// detections carry orientations).
    #[arg(long)]
    pub no_in_hand: bool,
    /// Label the motion in the hand with the pose smoother's parameters and
    /// the contact frame of FILE (written by `--save-in-hand`), neither
    /// tuned nor estimated here: a test split labelled with what the
    /// training split gave.
    #[arg(long, value_name = "FILE", conflicts_with = "no_in_hand")]
    pub in_hand: Option<PathBuf>,
    /// With --jointly: write the pose smoother's parameters and the contact
    /// frame estimated over the files to FILE (JSON).
    #[arg(long, value_name = "FILE", requires = "jointly", conflicts_with = "in_hand")]
    pub save_in_hand: Option<PathBuf>,
    /// The camera's pose in the hand frame, `X,Y,Z,QX,QY,QZ,QW` (m,
    /// quaternion); default: the rig configuration's camera placement when
    /// the session has one, else the identity (a camera riding on the hand,
    /// as on the imanlab rigs).
    #[arg(long, value_name = "X,Y,Z,QX,QY,QZ,QW", value_delimiter = ',', num_args = 7)]
    pub hand_from_camera: Option<Vec<f64>>,
    /// A hand calibration (the `[camera] placement` that `calibrate hand
    /// --out` writes, optionally with the hand's `[hand_geometry]`): the
    /// marker's positions and poses are moved into the hand frame with it,
    /// and the sliding axis (closing x fingers) and the gripper's contact
    /// frame come from the hand's geometry (this file's `[hand_geometry]`,
    /// else the session's rig config's, else the defaults) instead of
    /// `--axis`, the rig config's placement or an estimate.
    #[arg(long, value_name = "FILE", conflicts_with_all = ["axis", "hand_from_camera", "in_hand"])]
    pub hand_calibration: Option<PathBuf>,
    /// Recordings without the protocol: the normal load (sum of the
    /// baseline-subtracted z counts of every taxel) at which the hold begins.
    #[arg(long, value_name = "COUNTS", default_value_t = slidetrack_experiment::labelling::DEFAULT_CONTACT_LOAD_COUNTS)]
    pub contact_load: f64,
    /// Recordings without the protocol: time after the contact load is
    /// reached before the hold counts (s), while the gripper still closes.
    #[arg(long, value_name = "S", default_value_t = slidetrack_experiment::labelling::DEFAULT_SETTLE_S)]
    pub hold_settle: f64,
    /// The recordings start with the object already held (their tare is the
    /// grasped state, as xela-psc's): the hold runs from the first scan with
    /// a marker pose to the last.
    #[arg(long)]
    pub hold_from_start: bool,
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
    /// CAN traffic captured with can-utils: a `candump -l` log, or candump's
    /// console output (`candump can0 > dump.txt`, with or without `-t a`,
    /// `-t z` or `-t d` times), decoded in the configured layout (`--config`;
    /// the legacy layout by default).
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
    /// The times in the CAN log are gaps since the previous frame (`candump -t d`).
    #[arg(long)]
    pub time_deltas: bool,
    /// Replace the output file if it exists.
    #[arg(long)]
    pub overwrite: bool,
}
