//! `slidetrack import`: recordings made elsewhere turned into sessions
//! (`xela-csv` for xela-imanlab, `xela-psc`).

use std::path::PathBuf;

use clap::{Args, Subcommand};

/// `slidetrack import`.
#[derive(Debug, Args)]
pub struct ImportArgs {
    /// The kind of recording.
    #[command(subcommand)]
    pub what: ImportCommand,
}

/// The importers.
#[derive(Debug, Subcommand)]
pub enum ImportCommand {
    /// The xela-imanlab CSV recordings (two uSkin 4x4 patches on a Franka
    /// Panda, two ArUco markers seen by a wrist camera): one session per
    /// sequence folder, named after it.
    XelaCsv(RecordingDirsArgs),
    /// The xela-psc CSV trials (imanlab's proactive-slip-control data set:
    /// two uSkin 4x4 patches on a Franka Panda moving a box ever faster, one
    /// ArUco marker seen by a wrist camera, slip labels): one session per
    /// trial folder, named after it.
    XelaPsc(RecordingDirsArgs),
}

/// `slidetrack import xela-csv` and `xela-psc`: folders of recordings in, sessions out.
#[derive(Debug, Args)]
pub struct RecordingDirsArgs {
    /// Recording folders (`data_sample_<date>`, holding `xela_sensor1.csv`)
    /// or folders of them (such as xela-imanlab's `train/` or xela-psc's
    /// `data_set/`).
    #[arg(required = true, value_name = "DIR")]
    pub dirs: Vec<PathBuf>,
    /// Folder to write the sessions to (created if missing).
    #[arg(long, value_name = "OUTDIR")]
    pub out: PathBuf,
    /// Replace sessions that exist already.
    #[arg(long)]
    pub overwrite: bool,
    /// One JSON object per imported recording instead of text.
    #[arg(long)]
    pub json: bool,
}
