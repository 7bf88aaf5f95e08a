//! `--live` and `--ros2`: the Foxglove server and the ROS 2 topics beside a
//! recording run.

use anyhow::Result;
use slidetrack_experiment::live_view::LiveView;
use slidetrack_experiment::outlets::{Outlets, Ros2Topics};

use crate::cli::LiveArgs;

/// Starts the live view and the ROS 2 topics `args` asks for, before any
/// device moves; prints where they are on stderr (one line each).
pub fn start(args: &LiveArgs) -> Result<Outlets> {
    let mut outlets = Outlets::default();
    if let Some(addr) = &args.live {
        let view = LiveView::start(addr, args.live_image_hz)?;
        eprintln!(
            "live: Foxglove WebSocket server on {} (Foxglove: Open connection > Foxglove WebSocket)",
            view.url()
        );
        if let Some(timeout_s) = args.live_wait {
            eprintln!("live: waiting up to {timeout_s} s for a viewer before the trial starts");
            view.wait_for_viewer(timeout_s)?;
        }
        outlets.live = Some(view);
    }
    if args.ros2 {
        let ros2 = Ros2Topics::start(args.ros2_domain)?;
        eprintln!("ros2: publishing on ROS 2 domain {} (topics and types: docs/ros2.md)", ros2.domain());
        outlets.ros2 = Some(ros2);
    }
    Ok(outlets)
}

/// Stops the outlets after the run, saying what they could not send.
pub fn finish(outlets: Outlets) {
    if let Some(view) = outlets.live {
        let stats = view.finish();
        tracing::info!(
            "live: {} messages published, {} images thinned out, {} dropped because the publisher fell behind",
            stats.published,
            stats.images_throttled,
            stats.tap.dropped
        );
    }
    if let Some(ros2) = outlets.ros2 {
        let stats = ros2.finish();
        tracing::info!(
            "ros2: {} messages published, {} not published, {} dropped because the publisher fell behind",
            stats.node.published,
            stats.node.failed,
            stats.tap.dropped
        );
    }
}
