//! `slidetrack play`: a recorded session served to Foxglove at its recorded timing.

use std::sync::atomic::Ordering;

use anyhow::{Result, bail};
use slidetrack_experiment::live_view::{PlayOptions, play};

use crate::cli::PlayArgs;

pub fn run(args: &PlayArgs) -> Result<()> {
    if !(args.rate.is_finite() && args.rate > 0.0) {
        bail!("--rate must be a positive factor of the recorded timing, got {}", args.rate);
    }
    let options = PlayOptions {
        addr: args.live.clone(),
        rate: args.rate,
        looping: args.looping,
        wait_for_viewer: !args.no_wait,
    };
    let stop = super::stop_flag("ending the playback");
    let file = args.file.display().to_string();
    let wait = !args.no_wait;
    let report = play(&args.file, &options, &stop, &mut |addr| {
        let when = if wait { ", playing once a viewer subscribes" } else { "" };
        eprintln!("play: {file} on ws://{addr}{when} (Foxglove: Open connection > Foxglove WebSocket)");
    })?;
    println!("{file}: {} messages played, end reached {} time(s)", report.messages, report.endings);
    if stop.load(Ordering::SeqCst) && report.endings == 0 {
        bail!("interrupted");
    }
    Ok(())
}
