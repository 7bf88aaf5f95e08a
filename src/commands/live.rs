//! `--live`: the Foxglove server beside a recording run.

use anyhow::Result;
use slidetrack_experiment::live_view::LiveView;

use crate::cli::LiveArgs;

/// Starts the live view `args` asks for, before any device moves; prints its
/// address on stderr (one line).
pub fn start(args: &LiveArgs) -> Result<Option<LiveView>> {
    let Some(addr) = &args.live else { return Ok(None) };
    let view = LiveView::start(addr, args.live_image_hz)?;
    eprintln!(
        "live: Foxglove WebSocket server on {} (Foxglove: Open connection > Foxglove WebSocket)",
        view.url()
    );
    Ok(Some(view))
}

/// Stops the live view after the run, saying what it could not send.
pub fn finish(view: Option<LiveView>) {
    let Some(view) = view else { return };
    let stats = view.finish();
    tracing::info!(
        "live: {} messages published, {} images thinned out, {} dropped because the publisher fell behind",
        stats.published,
        stats.images_throttled,
        stats.tap.dropped
    );
}
