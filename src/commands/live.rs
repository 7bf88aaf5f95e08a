//! `--live`: the Foxglove server beside a recording run.

use anyhow::{Result, bail};
use slidetrack_live::{LiveOptions, LiveServer};

use crate::cli::LiveArgs;

/// Starts the live view `args` asks for, before any device moves; prints its
/// address on stderr (one line).
pub fn start(args: &LiveArgs) -> Result<Option<LiveServer>> {
    let Some(addr) = &args.live else { return Ok(None) };
    if !(args.live_image_hz.is_finite() && args.live_image_hz >= 0.0) {
        bail!("--live-image-hz must be 0 (every image) or a positive rate, got {}", args.live_image_hz);
    }
    let options = LiveOptions { image_max_hz: args.live_image_hz, ..LiveOptions::default() };
    let server = LiveServer::start(addr, &options)?;
    eprintln!(
        "live: Foxglove WebSocket server on {} (Foxglove: Open connection > Foxglove WebSocket)",
        server.url()
    );
    Ok(Some(server))
}

/// Stops the live view after the run, saying what it could not send.
pub fn finish(server: Option<LiveServer>) {
    let Some(server) = server else { return };
    let stats = server.shutdown();
    tracing::info!(
        "live: {} messages published, {} images thinned out, {} dropped because the publisher fell behind",
        stats.published,
        stats.images_throttled,
        stats.tap.dropped
    );
}
