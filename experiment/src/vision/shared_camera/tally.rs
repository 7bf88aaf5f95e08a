//! What the shared camera read, recorded and dropped: live counters for
//! its threads, a snapshot for the end of the trial and the session.

use std::sync::atomic::{AtomicU64, Ordering};

/// Counts of the shared camera, live.
#[derive(Debug, Default)]
pub(super) struct Tally {
    pub(super) read: AtomicU64,
    pub(super) recorded: AtomicU64,
    pub(super) dropped_recorder_behind: AtomicU64,
    pub(super) dropped_writer_behind: AtomicU64,
    pub(super) dropped_marker_behind: AtomicU64,
    pub(super) dropped_vision_behind: AtomicU64,
}

/// A snapshot of [`Tally`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TallyCounts {
    /// Pairs read from the camera.
    pub read: u64,
    /// Pairs whose colour and depth the session's writer took.
    pub recorded: u64,
    /// Pairs dropped before encoding: the recorder was behind.
    pub dropped_recorder_behind: u64,
    /// Pairs the session's writer refused (in part) while it was behind.
    pub dropped_writer_behind: u64,
    /// Colour frames the trial's marker detection was too slow to take.
    pub dropped_marker_behind: u64,
    /// Pairs a live vision tracker was too slow to take.
    pub dropped_vision_behind: u64,
}

/// Name of the session's metadata record of the shared camera's counts
/// (the fields of [`TallyCounts`], decimal).
pub const RGBD_CAMERA_METADATA: &str = "rgbd_camera";

impl TallyCounts {
    /// The counts as a metadata record.
    pub(super) fn to_map(self) -> std::collections::BTreeMap<String, String> {
        [
            ("pairs_read", self.read),
            ("pairs_recorded", self.recorded),
            ("dropped_recorder_behind", self.dropped_recorder_behind),
            ("dropped_writer_behind", self.dropped_writer_behind),
            ("dropped_marker_behind", self.dropped_marker_behind),
            ("dropped_vision_behind", self.dropped_vision_behind),
        ]
        .into_iter()
        .map(|(k, v)| (k.to_string(), v.to_string()))
        .collect()
    }
}

impl Tally {
    pub(super) fn counts(&self) -> TallyCounts {
        let get = |c: &AtomicU64| c.load(Ordering::SeqCst);
        TallyCounts {
            read: get(&self.read),
            recorded: get(&self.recorded),
            dropped_recorder_behind: get(&self.dropped_recorder_behind),
            dropped_writer_behind: get(&self.dropped_writer_behind),
            dropped_marker_behind: get(&self.dropped_marker_behind),
            dropped_vision_behind: get(&self.dropped_vision_behind),
        }
    }

    pub(super) fn line(&self) -> String {
        let c = self.counts();
        format!(
            "rgbd camera: {} pairs read, {} recorded; dropped: {} while the recorder was behind, {} while \
             the session writer was behind, {} colour frames while the marker detection was behind, {} pairs \
             while the vision tracker was behind",
            c.read,
            c.recorded,
            c.dropped_recorder_behind,
            c.dropped_writer_behind,
            c.dropped_marker_behind,
            c.dropped_vision_behind
        )
    }

    /// Counts one drop in `counter`, warning the first time the camera drops.
    pub(super) fn drop_one(&self, counter: &AtomicU64, why: &str) {
        if counter.fetch_add(1, Ordering::SeqCst) == 0 {
            tracing::warn!("rgbd camera: {why}: dropping pairs (counted; see the end of the trial)");
        }
    }
}
