//! `slidetrack vision simulate`: a simulated RGB-D session of a fast object.

use anyhow::Result;
use indicatif::{ProgressBar, ProgressStyle};
use slidetrack_experiment::vision::simulate::{SimulateOptions, SimulatedSession};

use crate::cli::VisionSimulateArgs as SimulateArgs;

pub fn run(args: &SimulateArgs, quiet: bool) -> Result<()> {
    let options = SimulateOptions {
        object: args.object.clone(),
        duration_s: args.duration,
        seed: args.seed,
        max_speed_mps: args.max_speed,
        max_angular_speed_dps: args.max_angular_speed,
        marker: args.marker.clone(),
        marker_size_m: args.marker_size,
        out: args.out.clone(),
        overwrite: args.overwrite,
    };
    let session = SimulatedSession::create(&options)?;
    if let Some(warning) = session.marker_warning() {
        eprintln!("{warning}");
    }
    let bar = if quiet { ProgressBar::hidden() } else { ProgressBar::new(session.len() as u64) };
    bar.set_style(ProgressStyle::with_template("{bar:40} {pos}/{len} frames {eta}")?);
    let summary = session.write(&mut || bar.inc(1))?;
    bar.finish_and_clear();
    println!(
        "{}: {} frames of {} at 30 Hz, network results {} ({} outliers)",
        summary.out.display(),
        summary.frames,
        summary.object,
        summary.network_results,
        summary.outliers
    );
    if let Some(path) = &summary.aruco_config {
        println!("marker configuration for --measurements aruco: {}", path.display());
    }
    Ok(())
}
