//! Arguments of the live view: `--live` of the commands that record, and `play`.

use std::path::PathBuf;

use clap::Args;
use slidetrack_experiment::live_view::DEFAULT_LIVE_ADDR;

/// Publishing a run live to Foxglove or as ROS 2 topics (`collect`, `track`, `record`).
#[derive(Debug, Args, Clone, PartialEq)]
pub struct LiveArgs {
    /// Also publish every recorded channel live, same topics and schemas, to
    /// Foxglove over its WebSocket protocol on ADDR (HOST:PORT; port 0 picks
    /// a free one). The bound address is printed on stderr; the recording
    /// does not wait for a viewer (see --live-wait).
    #[arg(long, value_name = "ADDR", num_args = 0..=1, default_missing_value = DEFAULT_LIVE_ADDR)]
    pub live: Option<String>,
    /// With --live: most camera images per second sent to viewers (0: every
    /// one). Only images are thinned; the session keeps them all.
    #[arg(long, value_name = "HZ", default_value_t = 15.0, requires = "live")]
    pub live_image_hz: f64,
    /// With --live: start only once a viewer has connected, waiting at most
    /// SECONDS (60 when no value is given); no viewer by then is an error
    /// before any device moves. Without it the recording never waits.
    #[arg(long, value_name = "SECONDS", num_args = 0..=1, default_missing_value = "60", requires = "live")]
    pub live_wait: Option<f64>,
    /// Also publish the recorded tactile scans, hand state, estimates,
    /// images and /tf as ROS 2 topics over DDS (no ROS installation needed;
    /// see docs/ros2.md). The recording never waits for a subscriber.
    #[arg(long)]
    pub ros2: bool,
    /// With --ros2: the ROS 2 domain id (default: ROS_DOMAIN_ID, else 0).
    #[arg(long, value_name = "N", requires = "ros2")]
    pub ros2_domain: Option<u32>,
}

/// Arguments of `play`.
#[derive(Debug, Args)]
pub struct PlayArgs {
    /// The session to play.
    pub file: PathBuf,
    /// Playback speed: 1 plays at the recorded timing, 10 ten times as fast.
    #[arg(long, default_value_t = 1.0)]
    pub rate: f64,
    /// Start again from the beginning at the end, until Ctrl-C.
    #[arg(long = "loop")]
    pub looping: bool,
    /// Where to serve Foxglove's WebSocket protocol (HOST:PORT; port 0 picks a free one).
    #[arg(long, value_name = "ADDR", default_value = DEFAULT_LIVE_ADDR)]
    pub live: String,
    /// Start playing at once, instead of when the first viewer subscribes.
    #[arg(long)]
    pub no_wait: bool,
    /// Publish the session as ROS 2 topics over DDS instead of serving
    /// Foxglove (the topics and types of `--ros2` on a recording run, see
    /// docs/ros2.md); the topics are announced 1 s before the first message.
    #[arg(long, conflicts_with = "no_wait")]
    pub ros2: bool,
    /// With --ros2: the ROS 2 domain id (default: ROS_DOMAIN_ID, else 0).
    #[arg(long, value_name = "N", requires = "ros2")]
    pub ros2_domain: Option<u32>,
}
