//! `slidetrack replay`: run the grasp-state detector and, with `--model`, a
//! dEKF model over a recorded session (through the replay rig, as `track`
//! runs them live; imported sessions over their recorded scans) and write a
//! copy of the session with their estimates.

use anyhow::Result;
use slidetrack_experiment::plot::dekf::plot_replay;
use slidetrack_experiment::replay_file::{ReplayFileOptions, replay_into_copy};

use crate::cli::ReplayArgs;

pub fn run_cmd(args: &ReplayArgs) -> Result<()> {
    let replayed = replay_into_copy(&ReplayFileOptions {
        file: args.file.clone(),
        model: args.model.clone(),
        out: args.out.clone(),
        overwrite: args.overwrite,
    })?;
    let estimates = &replayed.estimates;
    let dekf =
        if replayed.with_model { format!(", {} dEKF steps", estimates.dekf.len()) } else { String::new() };
    println!("{}: {} grasp-detector scans{dekf}", args.out.display(), estimates.slip.len());
    if let Some(plot) = &args.plot {
        plot_replay(&args.file, &estimates.dekf, plot)?;
        println!("{}", plot.display());
    }
    Ok(())
}
