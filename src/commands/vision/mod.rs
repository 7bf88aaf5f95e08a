//! `slidetrack vision`: the vision trackers MaskUKF and ROFT (thesis
//! Chapters 4 and 5) on simulated, recorded and dataset RGB-D input.

mod eval;
mod live;
mod simulate;
mod track;

use anyhow::Result;

use crate::cli::{VisionArgs, VisionCommand};

/// Runs a `vision` command.
pub fn run(args: &VisionArgs, quiet: bool) -> Result<()> {
    match &args.command {
        VisionCommand::Simulate(a) => simulate::run(a, quiet),
        VisionCommand::Track(a) if a.input.is_none() => live::run(a, quiet),
        VisionCommand::Track(a) => track::run(a, quiet),
        VisionCommand::Eval(a) => eval::run(a, quiet),
    }
}
