//! Arguments of the dEKF commands: `train`, `replay`, `eval`, `study`.

use std::path::PathBuf;

use clap::{Args, ValueEnum};
use slidetrack_experiment::dataset::TruthSource;
use slidetrack_experiment::dekf_train::model_options::{
    Activation, Batching, DEFAULT_OUTLIER_GATE_SIGMA, DEFAULT_PART_WINDOWS, Measurement, StateKind,
};
use slidetrack_experiment::dekf_train::{DEFAULT_CLIP_NORM, DEFAULT_POSITION_SHIFT_CM};
use slidetrack_experiment::protocol::Protocol;

/// Which truth to train and score against, on the command line.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum TruthArg {
    /// `/ground_truth/sliding` from `slidetrack label`.
    GroundTruth,
    /// `/ground_truth/thesis/sliding` from `slidetrack label --thesis --slot
    /// thesis` (the smoother with the thesis's parameters).
    ThesisGroundTruth,
    /// `/sim/truth`, the simulator's own (simulated sessions only).
    Sim,
}

impl From<TruthArg> for TruthSource {
    fn from(t: TruthArg) -> TruthSource {
        match t {
            TruthArg::GroundTruth => TruthSource::GroundTruth,
            TruthArg::ThesisGroundTruth => TruthSource::ThesisGroundTruth,
            TruthArg::Sim => TruthSource::Sim,
        }
    }
}

/// How `train` groups windows into batches.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum BatchingArg {
    /// Every window of every session shuffled together.
    Windows,
    /// Sets of sessions, one window position of each per batch.
    Sequences,
}

impl From<BatchingArg> for Batching {
    fn from(b: BatchingArg) -> Batching {
        match b {
            BatchingArg::Windows => Batching::Windows,
            BatchingArg::Sequences => Batching::Sequences,
        }
    }
}

/// A protocol of `study`, on the command line.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum ProtocolArg {
    /// This project's: ground truth with the smoother's defaults and the
    /// 5-sigma gate, windows shifted along the axis, best epoch kept.
    Default,
    /// Thesis Sec. 6.2.3-6.2.4 as written: the thesis's smoother (into
    /// `/ground_truth/thesis/...`), no shift, the last epoch.
    Thesis,
}

impl From<ProtocolArg> for Protocol {
    fn from(p: ProtocolArg) -> Protocol {
        match p {
            ProtocolArg::Default => Protocol::Default,
            ProtocolArg::Thesis => Protocol::Thesis,
        }
    }
}

/// What the feature network reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum MeasurementArg {
    /// The derivative of the tactile signal (the thesis's choice).
    Derivative,
    /// The plain baseline-subtracted signal (ablation of Table 6.3).
    Raw,
}

/// The state a model tracks, on the command line.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum StateArg {
    /// Position and velocity along the sliding axis (the thesis's).
    Sliding,
    /// Planar slip in the contact plane: the grip point's two translations
    /// and the rotation about the contact normal, with their rates; trained
    /// and scored against `/ground_truth/planar` (written by `label`).
    Planar,
}

impl From<StateArg> for StateKind {
    fn from(s: StateArg) -> StateKind {
        match s {
            StateArg::Sliding => StateKind::Sliding,
            StateArg::Planar => StateKind::Planar,
        }
    }
}

/// The networks' activation, on the command line.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum ActivationArg {
    /// `max(x, 0)` (the thesis's).
    Relu,
    /// `tanh(x)`.
    Tanh,
    /// GELU, tanh approximation (PyTorch's `nn.GELU(approximate="tanh")`).
    Gelu,
}

impl From<ActivationArg> for Activation {
    fn from(a: ActivationArg) -> Activation {
        match a {
            ActivationArg::Relu => Activation::Relu,
            ActivationArg::Tanh => Activation::Tanh,
            ActivationArg::Gelu => Activation::Gelu,
        }
    }
}

/// Arguments of `train`.
#[derive(Debug, Args, Clone)]
pub struct TrainArgs {
    /// Labelled session files, or directories of them.
    #[arg(required = true)]
    pub sessions: Vec<PathBuf>,
    /// Tactile channels the model reads: a set of Table 6.2 (`xyz`, `xy`,
    /// `z`: those axes of every finger's reading), or channel names separated
    /// by commas: `finger.axis` (`thumb.x`), `sensor.taxel.axis`
    /// (`thumb.5.z`), `sensor.mean.axis` (`index.mean.y`).
    #[arg(long, default_value = "xy")]
    pub channels: String,
    /// What the model reads: the derivative of the signal or the signal.
    #[arg(long, value_enum, default_value_t = MeasurementArg::Derivative)]
    pub measurement: MeasurementArg,
    /// The state the model tracks: `sliding` (the thesis's, along one axis)
    /// or `planar` (in the contact plane, against `/ground_truth/planar`).
    #[arg(long, value_enum, default_value_t = StateArg::Sliding)]
    pub state: StateArg,
    /// Model file to write (.safetensors). The linear-map baseline fitted on
    /// the same sessions goes beside it (`MODEL.linear.safetensors`).
    #[arg(long)]
    pub out: PathBuf,
    /// Do not fit the linear-map baseline.
    #[arg(long)]
    pub no_linear: bool,
    /// Filter rate (Hz): the tactile stream is decimated to about this rate
    /// (the thesis trained at 30 Hz).
    #[arg(long, default_value_t = 30.0)]
    pub rate_hz: f64,
    /// Schedule as `length:epochs,...` (Sec. 6.2.4: 2:5,4:5,8:5,16:5,32:5).
    #[arg(long, default_value = "2:5,4:5,8:5,16:5,32:5")]
    pub schedule: String,
    /// Subsequences per batch.
    #[arg(long, default_value_t = 32)]
    pub batch: usize,
    /// How windows are grouped into batches: `windows` (all windows of all
    /// sessions shuffled together) or `sequences` (as thesis Sec. 2.5.3
    /// reads: sets of `--batch` sessions, one window position of each per batch).
    #[arg(long, value_enum, default_value_t = BatchingArg::Windows)]
    pub batching: BatchingArg,
    /// Adam's learning rate.
    #[arg(long, default_value_t = 1e-3)]
    pub lr: f64,
    /// Scale a batch's gradient down to this global norm when it is larger
    /// (the gradient of the mean loss); 0 never clips.
    #[arg(long, default_value_t = DEFAULT_CLIP_NORM)]
    pub clip_norm: f64,
    /// Seed of initialisation, shuffling and initial-state draws.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Width of every hidden layer of the three networks (Sec. 6.1.6: 64).
    #[arg(long, default_value_t = 64)]
    pub width: usize,
    /// Residual blocks after `shared.linear` in each network (Sec. 6.1.6:
    /// 3; the encoder always has its own one).
    #[arg(long, default_value_t = 3)]
    pub blocks: usize,
    /// The networks' activation (Sec. 6.1.6: relu).
    #[arg(long, value_enum, default_value_t = ActivationArg::Relu)]
    pub activation: ActivationArg,
    /// A protocol's training settings at once: `thesis` is Sec. 6.2.4 as
    /// written (no `--position-shift`, the last epoch, no `--outlier-gate`)
    /// and, unless `--truth` says otherwise, the thesis's ground truth
    /// (`/ground_truth/thesis/sliding`, from `slidetrack label --thesis
    /// --slot thesis`); `default` is this project's (the defaults below).
    #[arg(long, value_enum, conflicts_with_all = ["position_shift", "no_select", "outlier_gate"])]
    pub protocol: Option<ProtocolArg>,
    /// Shift each training window by a random offset along the sliding axis,
    /// uniform in +-this (cm), so that the networks cannot tie their output to
    /// where the object happens to be (see docs/dekf.md); 0 keeps the recorded
    /// positions, as the thesis did.
    #[arg(long, default_value_t = DEFAULT_POSITION_SHIFT_CM)]
    pub position_shift: f64,
    /// Keep the parameters of the last epoch instead of those of the epoch
    /// whose filter, run over whole training sessions, tracked the position best
    /// (checked after each epoch of the second half of the schedule).
    #[arg(long)]
    pub no_select: bool,
    /// Feed the feature network the measurement as it is, without dividing
    /// each channel by its standard deviation over the training data (and
    /// subtracting its mean), as the thesis states no normalisation.
    #[arg(long)]
    pub no_normalise: bool,
    /// Worker threads (0: all cores). The model is the same on any number.
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    /// Windows per part of a batch's gradient: a batch keeps up to
    /// `--batch / --part-windows` threads busy. The parts are summed in a
    /// fixed order, so the model depends on this (by float rounding) but
    /// not on `--threads`.
    #[arg(long, default_value_t = DEFAULT_PART_WINDOWS)]
    pub part_windows: usize,
    /// Truth to train against: the ArUco ground truth (default, or the
    /// thesis protocol's with `--protocol thesis`) or the simulator's.
    #[arg(long, value_enum)]
    pub truth: Option<TruthArg>,
    /// Also plot the training curve (state RMSE per epoch, Fig. 6.6).
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// Print a JSON summary instead of text.
    #[arg(long)]
    pub json: bool,
    /// Largest relative difference of a session's tactile rate from the
    /// first session's (and, recorded in the model, from the sessions it
    /// runs on); imported recordings whose tactile refresh varies need more
    /// than the default.
    #[arg(long, default_value_t = 0.05)]
    pub rate_tolerance: f64,
    /// Leave out tactile samples further than this many standard deviations
    /// from the derivative filter's prediction (isolated spikes), at most two
    /// scans in a row; 0 takes every sample. Stored in the model: the online
    /// filter runs with the same gate.
    #[arg(long, value_name = "SIGMA", default_value_t = DEFAULT_OUTLIER_GATE_SIGMA)]
    pub outlier_gate: f64,
}

/// Arguments of `replay`.
#[derive(Debug, Args, Clone)]
pub struct ReplayArgs {
    /// Session file (.mcap).
    pub file: PathBuf,
    /// Model file (.safetensors); without it only the grasp-state detector runs.
    #[arg(long)]
    pub model: Option<PathBuf>,
    /// Output session: a copy of FILE with `/estimate/slip` (the grasp-state
    /// detector) and, with --model, `/tactile/derivative` and `/estimate/dekf`.
    #[arg(long)]
    pub out: PathBuf,
    /// Also plot the dEKF's estimates against the truth (Fig. 6.9).
    #[arg(long, requires = "model")]
    pub plot: Option<PathBuf>,
    /// Replace OUT if it exists.
    #[arg(long)]
    pub overwrite: bool,
}

/// Arguments of `eval`.
#[derive(Debug, Args, Clone)]
pub struct EvalArgs {
    /// Model file (.safetensors).
    #[arg(long)]
    pub model: PathBuf,
    /// Session files (labelled), or directories of them.
    #[arg(required = true)]
    pub files: Vec<PathBuf>,
    /// Score against the ArUco ground truth (default) or the simulator's
    /// truth (planar models are scored against `/ground_truth/planar`).
    #[arg(long, value_enum, default_value_t = TruthArg::GroundTruth)]
    pub truth: TruthArg,
    /// The linear-map baseline to score beside the model (default: the one
    /// `train` wrote beside it, `MODEL.linear.safetensors`, when it exists).
    #[arg(long, value_name = "FILE")]
    pub linear: Option<PathBuf>,
    /// Print JSON instead of a table.
    #[arg(long)]
    pub json: bool,
}

/// Arguments of `study`.
#[derive(Debug, Args, Clone)]
pub struct StudyArgs {
    /// Directory of sessions, grouped by the object in their metadata; each
    /// object's sessions (sorted by name) are split 50/50 into training and
    /// testing sets. Objects without sessions there are collected into it
    /// first (see `--collect`), and unlabelled sessions are labelled.
    #[arg(long, default_value = "study/sessions")]
    pub sessions: PathBuf,
    /// Directory for the models and the tables (default `study` for the
    /// default protocol, `study-thesis` for the thesis's).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// How to label and train: `default` (this project's) or `thesis`
    /// (Sec. 6.2.3-6.2.4 as written). Both can share `--sessions`: each
    /// labels into its own ground-truth channels. `docs/dekf-study.md`
    /// lists the differences and their measured effects.
    #[arg(long, value_enum, default_value_t = ProtocolArg::Default)]
    pub protocol: ProtocolArg,
    /// A small, fast version: 3 + 3 sessions of 20 s per object collected
    /// without camera, trained against the simulator's truth with 2 epochs per length.
    #[arg(long)]
    pub quick: bool,
    /// Sessions to collect per object when the directory has none of it
    /// (default 50, as the thesis; 6 with `--quick`).
    #[arg(long)]
    pub collect: Option<u32>,
    /// Duration of the sliding cycles of collected sessions (s; default 60, 20 with `--quick`).
    #[arg(long)]
    pub duration: Option<f64>,
    /// Training schedule (default the thesis's 2:5,4:5,8:5,16:5,32:5).
    #[arg(long)]
    pub schedule: Option<String>,
    /// Truth to train and score against (default: the protocol's ArUco
    /// ground truth; `--quick`: the simulator's truth, as it collects no camera).
    #[arg(long, value_enum)]
    pub truth: Option<TruthArg>,
    /// Seed of the simulated rig and of the trainings.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Trainings run at the same time, one core each (0: every core).
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    /// Where the study's jobs run (collecting, labelling, training):
    /// `local` (here) or `slurm` (Slurm job arrays, one task per trial,
    /// session or model; see `--slurm` and `docs/cluster.md`).
    #[arg(long, value_enum, default_value_t = ExecutorArg::Local)]
    pub executor: ExecutorArg,
    /// Directory of the study's jobs: job files, results, Slurm scripts
    /// and logs (default `OUT/work`). A study run again runs only the jobs
    /// without a valid result there.
    #[arg(long)]
    pub work_dir: Option<PathBuf>,
    /// Settings of `--executor slurm` (TOML: partition, account, time, mem,
    /// sbatch_options, retries, ...; `docs/cluster.md`).
    #[arg(long)]
    pub slurm: Option<PathBuf>,
    /// Print a JSON report (each job's Slurm task ids, host and times, and
    /// the tables' files) instead of the tables.
    #[arg(long)]
    pub json: bool,
}

/// Where `study` runs its trainings.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum ExecutorArg {
    /// Here, `--threads` at a time.
    Local,
    /// As a Slurm job array.
    Slurm,
}

/// Arguments of the hidden `study-job`: one job of a study's work
/// directory, as a Slurm task runs it.
#[derive(Debug, Args, Clone)]
pub struct StudyJobArgs {
    /// After its own job, run the stage's other jobs that no task has
    /// taken (see `slurm.toml`'s `steal`).
    #[arg(long)]
    pub steal: bool,
    /// The study's work directory.
    pub work_dir: PathBuf,
    /// The job's index (the array task id).
    pub index: usize,
}

impl From<MeasurementArg> for Measurement {
    fn from(m: MeasurementArg) -> Measurement {
        match m {
            MeasurementArg::Derivative => Measurement::Derivative,
            MeasurementArg::Raw => Measurement::Raw,
        }
    }
}
