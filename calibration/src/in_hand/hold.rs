//! The hold: the tactile scans during which the object is in the hand.

use serde::{Deserialize, Serialize};
use slidetrack_core::TimeNs;
use slidetrack_estimators::slip::{GraspDetector, GraspDetectorConfig, GraspScan, GraspState};

/// How the hold of a recording without the protocol is found.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct HoldOptions {
    /// The grasp detector's settings: the hold begins when the normal load
    /// reaches its contact level and ends when it declares the object
    /// dropped or released.
    pub detector: GraspDetectorConfig,
    /// Time after the contact level is reached before the hold counts (s):
    /// the gripper is still closing and centring the object then.
    pub settle_s: f64,
    /// The recording starts with the object already held (its tare is the
    /// grasped state, as in xela-psc): the hold runs from the first scan to
    /// the marker's last sighting.
    #[serde(default)]
    pub from_start: bool,
}

impl Default for HoldOptions {
    fn default() -> Self {
        HoldOptions {
            detector: GraspDetectorConfig::default(),
            settle_s: DEFAULT_SETTLE_S,
            from_start: false,
        }
    }
}

/// Default [`HoldOptions::settle_s`] (s): on the imanlab rigs the load rises
/// for about half a second after first contact while the gripper closes.
pub const DEFAULT_SETTLE_S: f64 = 0.5;

/// The scans of a hold: indices `start..end` into a session's scan list.
#[derive(Clone, Debug, PartialEq)]
pub struct Hold {
    /// First scan of the hold.
    pub start: usize,
    /// One past its last scan.
    pub end: usize,
    /// How its ends were found, in words.
    pub how: String,
}

/// What the hold is found from.
pub struct HoldInputs<'a> {
    /// The scans (log times), increasing.
    pub scans: &'a [TimeNs],
    /// The normal load at each zeroed scan `(time, counts)`, when recorded.
    pub loads: &'a [(TimeNs, f64)],
    /// The start of the sliding cycles (protocol sessions).
    pub cycles: Option<TimeNs>,
    /// The release (protocol sessions).
    pub release: Option<TimeNs>,
}

/// The hold among `inputs.scans`: the protocol's cycles when the session
/// has them, else from the loads with `options`. `None` when there is no
/// hold of at least two scans.
pub fn find_hold(inputs: &HoldInputs, options: &HoldOptions) -> Option<Hold> {
    let scans = inputs.scans;
    let index_at = |t: TimeNs| scans.iter().take_while(|s| **s < t).count();
    let (start, end, how) = if let Some(cycles) = inputs.cycles {
        let end = inputs.release.map_or(scans.len(), index_at);
        (
            index_at(cycles),
            end,
            "from the start of the sliding cycles to the release (protocol events)".to_string(),
        )
    } else if options.from_start {
        (
            0,
            scans.len(),
            "the whole recording with marker poses (it starts in grasp: --hold-from-start)".to_string(),
        )
    } else {
        let (contact, lost) = contact_and_loss(inputs, &options.detector)?;
        let settle_ns = (options.settle_s.max(0.0) * 1e9) as u64;
        let start = index_at(TimeNs(contact.0.saturating_add(settle_ns)));
        let end = lost.map_or(scans.len(), index_at);
        let how = format!(
            "from {:.3} s after the normal load first reached {} counts ({:.3} s) to {}",
            options.settle_s,
            options.detector.contact_load_counts,
            contact.secs_since(scans[0]),
            lost.map_or("the marker's last sighting".to_string(), |t| format!(
                "the grasp detector's drop or release at {:.3} s (load below {} of its peak)",
                t.secs_since(scans[0]),
                options.detector.drop_load_ratio
            ))
        );
        (start, end, how)
    };
    (end >= start + 2).then_some(Hold { start, end, how })
}

/// When the load first made contact, and when the detector then declared
/// the object dropped or released; `None` without contact.
fn contact_and_loss(inputs: &HoldInputs, cfg: &GraspDetectorConfig) -> Option<(TimeNs, Option<TimeNs>)> {
    let mut detector = GraspDetector::new(*cfg).ok()?;
    let mut loads = inputs.loads.iter().peekable();
    let mut load = None;
    let mut contact = None;
    for t in inputs.scans {
        while let Some((_, l)) = loads.next_if(|(tl, _)| tl <= t) {
            load = Some(*l);
        }
        let Some(l) = load else { continue };
        let reading = detector.update(GraspScan::load(t.as_secs_f64(), l));
        match reading.state {
            GraspState::Holding | GraspState::Slipping if contact.is_none() => contact = Some(*t),
            GraspState::Dropped | GraspState::Released if contact.is_some() => {
                return Some((contact?, Some(*t)));
            }
            _ => {}
        }
    }
    contact.map(|c| (c, None))
}
