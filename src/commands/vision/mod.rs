//! `slidetrack vision`: the vision trackers MaskUKF and ROFT (thesis
//! Chapters 4 and 5) on simulated, recorded and dataset RGB-D input.

pub(crate) mod camera_vision;
mod eval;
mod inputs;
mod live;
pub(crate) mod live_camera;
mod simulate;
mod track;

use anyhow::Result;

use crate::cli::{VisionArgs, VisionCommand};

/// Runs a `vision` command.
pub fn run(args: &VisionArgs, quiet: bool) -> Result<()> {
    match &args.command {
        VisionCommand::Simulate(a) => simulate::run(a, quiet),
        VisionCommand::Track(a) => track::run(a, quiet),
        VisionCommand::Eval(a) => eval::run(a, quiet),
    }
}
