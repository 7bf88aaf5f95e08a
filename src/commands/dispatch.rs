//! Routes the command the user asked for to its module.

use anyhow::Result;

use crate::cli::{Cli, Command};

/// Runs the command the user asked for.
pub fn dispatch(cli: Cli) -> Result<()> {
    let quiet = cli.quiet;
    match cli.command {
        Command::Collect(args) => super::collect::run(&args, quiet),
        Command::Record(args) => super::record::run(&args, quiet),
        Command::Info(args) => super::info::run(&args),
        Command::Export(args) => super::export::run(&args),
        Command::Plot(args) => super::plot::run(&args),
        Command::Demo(args) => super::demo::run(&args, quiet),
        Command::Bench(args) => super::bench::run(&args),
        Command::Objects => super::objects::run(),
        Command::Train(args) => super::train::run(&args, quiet),
        Command::Replay(args) => super::replay::run_cmd(&args),
        Command::Eval(args) => super::eval::run_cmd(&args),
        Command::Slip(args) => super::slip::run(&args),
        Command::Track(args) => super::track::run(&args, quiet),
        Command::Study(args) => super::study::run(&args, quiet),
        Command::StudyJob(args) => super::study::run_job(&args),
        Command::Vision(args) => super::vision::run(&args, quiet),
        Command::Label(args) => super::label::run(&args, quiet),
        Command::Calibrate(args) => super::calibrate::run(&args, quiet),
        Command::Aruco(args) => super::aruco::run(&args),
        #[cfg(all(feature = "devices", target_os = "linux"))]
        Command::Devices(args) => super::devices::run(&args),
        #[cfg(not(all(feature = "devices", target_os = "linux")))]
        Command::Devices(_) => Err(super::without_devices("devices")),
        Command::Decode(args) => super::decode::run(&args, quiet),
        Command::Import(args) => super::import::run(&args, quiet),
        #[cfg(all(feature = "devices", target_os = "linux"))]
        Command::Emulate(args) => super::emulate::run(&args),
        #[cfg(not(all(feature = "devices", target_os = "linux")))]
        Command::Emulate(_) => Err(super::without_devices("emulate")),
        Command::Play(args) => super::play::run(&args),
    }
}
