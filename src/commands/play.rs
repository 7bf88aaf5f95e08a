//! `slidetrack play`: a recorded session served to Foxglove, or published as
//! ROS 2 topics, at its recorded timing.

use std::sync::atomic::Ordering;

use anyhow::{Result, bail};
use slidetrack_experiment::live_view::{PlayOptions, play};
use slidetrack_experiment::ros2_play::{Ros2PlayOptions, play_ros2};

use crate::cli::PlayArgs;

pub fn run(args: &PlayArgs) -> Result<()> {
    if !(args.rate.is_finite() && args.rate > 0.0) {
        bail!("--rate must be a positive factor of the recorded timing, got {}", args.rate);
    }
    if args.ros2 {
        return run_ros2(args);
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

/// `play --ros2`.
fn run_ros2(args: &PlayArgs) -> Result<()> {
    let options = Ros2PlayOptions {
        domain: args.ros2_domain,
        rate: args.rate,
        looping: args.looping,
        ..Ros2PlayOptions::default()
    };
    let stop = super::stop_flag("ending the playback");
    let file = args.file.display().to_string();
    let report = play_ros2(&args.file, &options, &stop, &mut |domain| {
        eprintln!("play: {file} on ROS 2 domain {domain} (topics and types: docs/ros2.md)");
    })?;
    let p = report.published;
    println!(
        "{file}: {} messages played, end reached {} time(s); ROS 2: {} published, {} not published, {} dropped",
        report.messages, report.endings, p.node.published, p.node.failed, p.tap.dropped
    );
    if stop.load(Ordering::SeqCst) && report.endings == 0 {
        bail!("interrupted");
    }
    Ok(())
}
