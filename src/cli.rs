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
}

/// Which rig runs the trial.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum RigKind {
    /// The simulated rig (physics model of the hand, object and sensors).
    Sim,
    /// The real rig, with the devices of the rig configuration.
    Hw,
}

/// Arguments of `collect`.
#[derive(Debug, Args)]
pub struct CollectArgs {
    /// The rig to run on.
    #[arg(long, value_enum, default_value_t = RigKind::Sim)]
    pub rig: RigKind,
    /// Object: a built-in name (box, bottle, mustard) or a path to an object .toml.
    #[arg(long, default_value = "box")]
    pub object: String,
    /// Number of trials, one session file each.
    #[arg(long, default_value_t = 1)]
    pub trials: u32,
    /// Index of the first trial (trials are numbered from it).
    #[arg(long, default_value_t = 0)]
    pub first_trial: u32,
    /// Duration of the sliding cycles of each trial (s).
    #[arg(long, default_value_t = 60.0)]
    pub duration: f64,
    /// Seed of the simulated rig; the same seed gives the same data.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Directory for the session files (created if missing).
    #[arg(long, default_value = "sessions")]
    pub out: PathBuf,
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

/// Arguments of `demo`.
#[derive(Debug, Args)]
pub struct DemoArgs {
    /// Directory for the demo's sessions and plots.
    #[arg(long, default_value = "demo-out")]
    pub out: PathBuf,
    /// Duration of the sliding cycles of each trial (s).
    #[arg(long, default_value_t = 60.0)]
    pub duration: f64,
    /// Seed of the simulated rig.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
}

/// Arguments of `bench`.
#[derive(Debug, Args)]
pub struct BenchArgs {
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
            (a.rig, a.object.as_str(), a.trials, a.duration, a.seed),
            (RigKind::Sim, "box", 10, 60.0, 1)
        );
        assert_eq!(a.out, PathBuf::from("DIR"));
        assert!(!a.no_camera);
    }

    #[test]
    fn unknown_rig_is_a_parse_error() {
        assert!(Cli::try_parse_from(["slidetrack", "collect", "--rig", "moon"]).is_err());
    }

    #[test]
    fn export_needs_a_channel() {
        assert!(Cli::try_parse_from(["slidetrack", "export", "x.mcap"]).is_err());
        assert!(Cli::try_parse_from(["slidetrack", "export", "x.mcap", "--channel", "/tactile/raw"]).is_ok());
    }
}
