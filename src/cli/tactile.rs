//! Arguments of `calibrate tactile`.

use std::path::PathBuf;

use clap::{Args, ValueEnum};

/// The terms of each taxel's map.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum ForceModelArg {
    /// A 3x3 matrix (gains and cross-talk) and an offset per taxel.
    Linear,
    /// The linear terms and the six second-order terms of the counts.
    Quadratic,
}

/// Arguments of `calibrate tactile`.
#[derive(Debug, Args)]
#[command(group(clap::ArgGroup::new("mode").required(true).args(["fit", "apply"])))]
pub struct CalibrateTactileArgs {
    /// Sessions to fit on: tared counts (`/tactile/zeroed`) and reference
    /// forces (`/tactile/reference`, from `[sim] reference_forces = true`).
    #[arg(long, num_args = 1.., value_name = "SESSION.mcap")]
    pub fit: Vec<PathBuf>,
    /// Held-out sessions to measure the maps on (default: the fit sessions).
    #[arg(long, num_args = 1.., value_name = "SESSION.mcap", requires = "fit")]
    pub eval: Vec<PathBuf>,
    /// The terms of each taxel's map.
    #[arg(long, value_enum, default_value = "quadratic")]
    pub model: ForceModelArg,
    /// Adds `/tactile/calibrated` to a copy of this session (written to --out).
    #[arg(long, value_name = "SESSION.mcap", requires_all = ["calibration", "out"], conflicts_with = "fit")]
    pub apply: Option<PathBuf>,
    /// The calibration file to apply (with --apply).
    #[arg(long, value_name = "CALIBRATION.toml", requires = "apply")]
    pub calibration: Option<PathBuf>,
    /// Where to write: the calibration file (fit) or the session copy (--apply).
    #[arg(long, short)]
    pub out: Option<PathBuf>,
    /// Replace --out if it exists.
    #[arg(long)]
    pub overwrite: bool,
    /// Print the errors as JSON.
    #[arg(long)]
    pub json: bool,
}
