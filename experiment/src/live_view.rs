//! The live view beside a run (`--live`): a Foxglove WebSocket server that
//! publishes what the run's recorder writes, and the playback of a recorded
//! session to Foxglove (`play`).

use anyhow::{Result, bail};
use slidetrack_live::{LiveOptions, LiveServer};
use slidetrack_session::LiveTap;

pub use slidetrack_live::{DEFAULT_LIVE_ADDR, LiveStats, PlayOptions, PlayReport, play};

/// A live view serving a run.
pub struct LiveView {
    server: LiveServer,
}

impl LiveView {
    /// Starts a server on `addr` (`HOST:PORT`; port 0 picks a free one)
    /// sending at most `image_max_hz` camera images per second to viewers
    /// (0: every one). It binds before returning: an address that cannot
    /// serve fails here, before any device moves.
    pub fn start(addr: &str, image_max_hz: f64) -> Result<LiveView> {
        if !(image_max_hz.is_finite() && image_max_hz >= 0.0) {
            bail!("--live-image-hz must be 0 (every image) or a positive rate, got {image_max_hz}");
        }
        let options = LiveOptions { image_max_hz, ..LiveOptions::default() };
        Ok(LiveView { server: LiveServer::start(addr, &options)? })
    }

    /// The address viewers connect to (`ws://HOST:PORT`).
    pub fn url(&self) -> String {
        self.server.url()
    }

    /// Waits until a viewer is connected, at most `timeout_s` seconds;
    /// an error naming the address when none came.
    pub fn wait_for_viewer(&self, timeout_s: f64) -> Result<()> {
        if !(timeout_s.is_finite() && timeout_s > 0.0) {
            bail!("--live-wait must be a positive number of seconds, got {timeout_s}");
        }
        if !self.server.wait_for_viewer(std::time::Duration::from_secs_f64(timeout_s)) {
            bail!(
                "no viewer connected to {} within {timeout_s} s (--live-wait); nothing was recorded",
                self.url()
            );
        }
        Ok(())
    }

    /// Where a recorder hands what it writes.
    pub fn tap(&self) -> LiveTap {
        self.server.tap()
    }

    /// Stops the server; what it published, thinned out and dropped.
    pub fn finish(self) -> LiveStats {
        self.server.shutdown()
    }
}
