//! What a recording run publishes beside its session: the Foxglove live
//! view (`--live`) and ROS 2 topics (`--ros2`). Both take what the
//! recorder writes from a [`LiveTap`], which never waits for them.

use anyhow::{Context, Result};
use slidetrack_ros2::{Ros2Options, Ros2Publisher, domain_id};
use slidetrack_session::LiveTap;

use crate::live_view::LiveView;

pub use slidetrack_ros2::Ros2Stats;

/// ROS 2 topics of a run: a DDS participant publishing what the recorder writes.
pub struct Ros2Topics {
    publisher: Ros2Publisher,
}

impl Ros2Topics {
    /// Joins ROS 2 domain `domain` (`None`: `ROS_DOMAIN_ID`, else 0) before
    /// any device moves: a domain that cannot be joined fails here.
    pub fn start(domain: Option<u32>) -> Result<Ros2Topics> {
        let domain = domain_id(domain)?;
        let options = Ros2Options { domain, ..Ros2Options::default() };
        let publisher = Ros2Publisher::start(&options).context("--ros2")?;
        Ok(Ros2Topics { publisher })
    }

    /// The domain it publishes on.
    pub fn domain(&self) -> u16 {
        self.publisher.domain()
    }

    /// Where a recorder (or a played session) hands what it writes.
    pub fn tap(&self) -> LiveTap {
        self.publisher.tap()
    }

    /// Publishes what is still queued and leaves the domain.
    pub fn finish(self) -> Ros2Stats {
        self.publisher.finish()
    }
}

/// The outlets of a run (either, both or none).
#[derive(Default)]
pub struct Outlets {
    /// The Foxglove live view.
    pub live: Option<LiveView>,
    /// ROS 2 topics.
    pub ros2: Option<Ros2Topics>,
}

impl Outlets {
    /// The tap to give the run's recorders: the live view's, the ROS 2
    /// publisher's, or with both one that hands everything to each.
    pub fn tap(&self) -> Option<LiveTap> {
        let live = self.live.as_ref().map(LiveView::tap);
        let ros2 = self.ros2.as_ref().map(Ros2Topics::tap);
        match (live, ros2) {
            (Some(live), Some(ros2)) => Some(live.and(&ros2)),
            (live, ros2) => live.or(ros2),
        }
    }
}
