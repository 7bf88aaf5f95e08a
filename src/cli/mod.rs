//! Command-line arguments: every argument struct of every command, in one
//! module (grouped by subject in its files). Commands read these types; this
//! module reads nothing of the commands.

mod camera;
mod dekf;
mod emulate;
mod experiment;
mod import;
mod live;
#[cfg(test)]
mod parse_tests;
mod session;
mod slip;
mod tactile;
mod vision;

use clap::{Parser, Subcommand};

pub use camera::*;
pub use dekf::*;
pub use emulate::*;
pub use experiment::*;
pub use import::*;
pub use live::*;
pub use session::*;
pub use slip::*;
pub use tactile::*;
pub use vision::*;

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
    /// Record the configured devices into a session without running the protocol.
    Record(RecordArgs),
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
    Vision(VisionArgs),
    /// Build the ground truth of sessions from the ArUco marker (RTS smoother).
    Label(LabelArgs),
    /// Calibrate a camera's intrinsics from pattern views, or tactile counts to newtons.
    Calibrate(CalibrateArgs),
    /// ArUco marker tools: detect markers (and their poses) in an image.
    Aruco(ArucoArgs),
    /// List the cameras (with their formats), serial ports and CAN interfaces present.
    Devices(DevicesArgs),
    /// Train a dEKF model on labelled sessions (BPTT, Sec. 6.2.4).
    Train(TrainArgs),
    /// Run the grasp-state detector and a dEKF model over a session; write a copy with their estimates.
    Replay(ReplayArgs),
    /// Score a dEKF model on labelled sessions (RMSE and max errors, Table 6.1).
    Eval(EvalArgs),
    /// Run the grasp-state detector over sessions: drops, false alarms, slip-label AUCs.
    Slip(SlipArgs),
    /// Run the experiment with the dEKF (and the marker filter) live, recorded to a session.
    Track(TrackArgs),
    /// The experiments of thesis Sec. 6.3 on the simulated rig: Tables 6.1-6.4.
    Study(StudyArgs),
    /// One job of a study's work directory (what a Slurm task of `study --executor slurm` runs).
    #[command(hide = true)]
    StudyJob(StudyJobArgs),
    /// Turn captured tactile traffic (candump log, raw serial bytes) into a session.
    Decode(DecodeArgs),
    /// Turn recordings made elsewhere (the xela-imanlab and xela-psc CSVs) into sessions.
    Import(ImportArgs),
    /// Serve an emulated device (Robotiq gripper, tactile sensors) where the real one would be.
    Emulate(EmulateArgs),
    /// Play a recorded session to Foxglove over its WebSocket protocol, at its recorded timing.
    Play(PlayArgs),
}

#[cfg(test)]
mod tests {
    use std::path::PathBuf;

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
            (RigArg::Sim, "box", 10, 60.0, 1)
        );
        assert_eq!(a.out, PathBuf::from("DIR"));
        assert!(!a.run.no_camera);
    }

    #[test]
    fn emulate_parses_its_devices() {
        let cli = Cli::try_parse_from([
            "slidetrack",
            "emulate",
            "robotiq",
            "--model",
            "hand-e",
            "--object-width-mm",
            "30",
        ])
        .unwrap();
        let Command::Emulate(EmulateArgs { device: EmulateDevice::Robotiq(a) }) = cli.command else {
            panic!("not emulate robotiq")
        };
        assert_eq!((a.model.as_str(), a.object_width_mm, a.device_id), ("hand-e", Some(30.0), 9));
        assert!(Cli::try_parse_from(["slidetrack", "emulate", "robotiq", "--model", "3f"]).is_err());
        assert!(Cli::try_parse_from(["slidetrack", "emulate", "robotiq", "--fault", "16"]).is_err());
        assert!(
            Cli::try_parse_from(["slidetrack", "emulate", "xela-server", "--config", "rig.toml"]).is_ok()
        );
        assert!(Cli::try_parse_from(["slidetrack", "emulate", "serial"]).is_err(), "--config is required");
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
    fn live_takes_an_optional_address_and_play_its_options() {
        let parse = |args: &[&str]| Cli::try_parse_from([&["slidetrack"], args].concat());
        let Command::Collect(a) = parse(&["collect", "--live", "--duration", "2"]).unwrap().command else {
            panic!("not collect")
        };
        assert_eq!((a.run.live.live.as_deref(), a.run.duration), (Some("127.0.0.1:8765"), 2.0));
        let Command::Track(a) = parse(&["track", "--model", "m", "--live", "0.0.0.0:9000"]).unwrap().command
        else {
            panic!("not track")
        };
        assert_eq!(a.run.live.live.as_deref(), Some("0.0.0.0:9000"));
        assert!(parse(&["collect", "--live-image-hz", "5"]).is_err(), "--live-image-hz needs --live");
        let Command::Play(p) = parse(&["play", "s.mcap", "--rate", "2", "--loop"]).unwrap().command else {
            panic!("not play")
        };
        assert_eq!((p.rate, p.looping, p.live.as_str()), (2.0, true, "127.0.0.1:8765"));
    }

    #[test]
    fn ros2_takes_a_domain_and_is_on_collect_track_and_record() {
        let parse = |args: &[&str]| Cli::try_parse_from([&["slidetrack"], args].concat());
        let Command::Track(a) =
            parse(&["track", "--model", "m", "--ros2", "--ros2-domain", "7"]).unwrap().command
        else {
            panic!("not track")
        };
        assert_eq!((a.run.live.ros2, a.run.live.ros2_domain), (true, Some(7)));
        let Command::Record(a) = parse(&["record", "--out", "o.mcap", "--ros2"]).unwrap().command else {
            panic!("not record")
        };
        assert_eq!((a.live.ros2, a.live.ros2_domain), (true, None));
        assert!(parse(&["collect", "--ros2-domain", "7"]).is_err(), "--ros2-domain needs --ros2");
        let Command::Collect(a) = parse(&["collect", "--ros2", "--live"]).unwrap().command else {
            panic!("collect")
        };
        assert!(a.run.live.ros2 && a.run.live.live.is_some(), "both outlets at once");
    }

    #[test]
    fn replay_runs_without_a_model_but_plots_only_with_one() {
        let parse = |args: &[&str]| Cli::try_parse_from([&["slidetrack", "replay", "s.mcap"], args].concat());
        let Command::Replay(a) = parse(&["--out", "o.mcap"]).unwrap().command else { panic!("not replay") };
        assert_eq!(a.model, None);
        assert!(parse(&["--out", "o.mcap", "--plot", "p.png"]).is_err(), "--plot needs --model");
        assert!(parse(&["--out", "o.mcap", "--plot", "p.png", "--model", "m"]).is_ok());
    }

    #[test]
    fn export_needs_a_channel() {
        assert!(Cli::try_parse_from(["slidetrack", "export", "x.mcap"]).is_err());
        assert!(Cli::try_parse_from(["slidetrack", "export", "x.mcap", "--channel", "/tactile/raw"]).is_ok());
        assert!(Cli::try_parse_from(["slidetrack", "export", "x.mcap", "--ros2-bag", "b.mcap"]).is_ok());
        let both = ["slidetrack", "export", "x.mcap", "--ros2-bag", "b.mcap", "--channel", "/tactile/raw"];
        assert!(Cli::try_parse_from(both).is_err(), "one export at a time");
    }
}
