//! The grasp-state stage ([`crate::grasp_state`]) run offline over recorded
//! sessions, and scored (`slidetrack slip`): drops against the tactile
//! release and the marker's last sighting, false alarms per minute held,
//! and the ROC-AUC of the slip score against recorded slip labels beside
//! that of the robot's speed.
//!
//! The stage reads the session's recorded `/tactile/zeroed` scans and
//! `/hand/state` openings in the order of the file (a hand state logged with
//! a scan applies from the next scan on, as live, where the hand's status is
//! read after the scan). The scores:
//!
//! - **tactile release**: [`tactile_release`] on the loads (the load stays
//!   below half its running peak from there on);
//! - **marker last seen**: the last `/aruco/detections` with `detected`;
//! - **drop delay**: the first Dropped reading minus the release, and minus
//!   the marker's last sighting;
//! - **false alarms**: entries into Dropped on sessions whose metadata
//!   (`xela_imanlab` or `xela_psc` record, `dropped`) says they were kept,
//!   per minute spent Holding or Slipping;
//! - **slip ROC-AUC**, where the session has `/slip/label`: one row per
//!   tactile scan, the label and the robot row (`/robot/state` `v_x_m_s`,
//!   `v_y_m_s`, the commanded end-effector velocity) the latest logged at or
//!   before the scan; the slip score and the robot speed `|(v_x, v_y)|` each
//!   ranked against `slip != 0`. On xela-psc the label follows the marker's
//!   motion and is confounded with the robot's speed (only the fastest
//!   trials have slip rows): the speed's AUC is reported beside the score's
//!   so the confound is visible.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use serde::{Deserialize, Serialize};
use slidetrack_core::TimeNs;
pub use slidetrack_estimators::slip::GraspDetectorConfig;
use slidetrack_estimators::slip::{
    GraspState, HoldSummary, drop_detection_delay_s, hold_summary, roc_auc, tactile_release,
};
use slidetrack_session::{
    ArucoDetection, ChannelMessage, HandState, MessageReader, ReadOptions, SessionInfo, SlipEstimate,
    TactileRaw, TactileZeroed, scan_of,
};

use crate::channels::recorded_tactile;
use crate::grasp_state::SlipStage;
use crate::import::xela_psc_session::{ROBOT_TOPIC, SLIP_TOPIC, SlipLabelMessage};

/// A drop counts as detected when the first Dropped reading lies within
/// this long of the tactile release (s).
pub const DROP_WINDOW_S: f64 = 0.3;

/// Metadata records of imported sessions that say whether the object was
/// dropped (key `dropped`, `true`/`false`).
pub const DROPPED_RECORDS: [&str; 2] = ["xela_imanlab", "xela_psc"];

/// The stage's output over one session and what it is scored against.
#[derive(Clone, Debug)]
pub struct SlipTrace {
    /// The session file.
    pub path: PathBuf,
    /// Whether the object was dropped, from the metadata; `None` when unknown.
    pub dropped: Option<bool>,
    /// Log time of every zeroed scan.
    pub times: Vec<TimeNs>,
    /// The `/estimate/slip` message of every scan.
    pub estimates: Vec<SlipEstimate>,
    /// The detector's state after every scan.
    pub states: Vec<GraspState>,
    /// Log time of the last marker detection with `detected`.
    pub marker_last_seen: Option<TimeNs>,
    /// The slip label at every scan (`slip != 0`), where the session has `/slip/label`.
    pub labels: Option<Vec<Option<bool>>>,
    /// The commanded end-effector speed at every scan (m/s), where
    /// `/robot/state` has `v_x_m_s` and `v_y_m_s`.
    pub robot_speed: Option<Vec<Option<f64>>>,
    /// The `/estimate/slip` channel metadata of the stage that ran.
    pub metadata: BTreeMap<String, String>,
}

/// `/robot/state`'s commanded velocity, when the schema has it (xela-psc).
#[derive(Deserialize)]
struct CommandedVelocity {
    v_x_m_s: Option<f64>,
    v_y_m_s: Option<f64>,
}

/// The time series a session's side channels give.
#[derive(Default)]
struct SideChannels {
    marker_last_seen: Option<TimeNs>,
    labels: Vec<(TimeNs, bool)>,
    robot_speed: Vec<(TimeNs, f64)>,
    has_labels: bool,
}

/// The dropped flag of the session's metadata, if any.
fn dropped_flag(info: &SessionInfo) -> Option<bool> {
    DROPPED_RECORDS
        .iter()
        .find_map(|r| info.metadata.get(*r).and_then(|m| m.get("dropped")).and_then(|d| d.parse().ok()))
}

/// The value of `series` (in time order) logged last at or before `t`.
fn at_or_before<T: Copy>(series: &[(TimeNs, T)], t: TimeNs) -> Option<T> {
    let n = series.partition_point(|(s, _)| *s <= t);
    n.checked_sub(1).map(|i| series[i].1)
}

/// Runs the stage with `cfg` over the recorded scans of `path`.
pub fn run_offline(path: &Path, cfg: GraspDetectorConfig) -> Result<SlipTrace> {
    let info = SessionInfo::read(path, ReadOptions::default())?;
    if info.channel(TactileZeroed::TOPIC).is_none() {
        bail!("{}: no baseline-subtracted tactile data ({})", path.display(), TactileZeroed::TOPIC);
    }
    let tactile = recorded_tactile(path, &info)?
        .with_context(|| format!("{}: no taxel layout on {}", path.display(), TactileRaw::TOPIC))?;
    let mut stage = SlipStage::new(cfg, &tactile)?;
    let mut trace = SlipTrace {
        path: path.to_path_buf(),
        dropped: dropped_flag(&info),
        times: Vec::new(),
        estimates: Vec::new(),
        states: Vec::new(),
        marker_last_seen: None,
        labels: None,
        robot_speed: None,
        metadata: stage.metadata()?,
    };
    let mut side = SideChannels { has_labels: info.channel(SLIP_TOPIC).is_some(), ..SideChannels::default() };
    let topics = [TactileZeroed::TOPIC, HandState::TOPIC, ArucoDetection::TOPIC, SLIP_TOPIC, ROBOT_TOPIC];
    for message in MessageReader::open(path, &topics, ReadOptions::default())? {
        let m = message?;
        let what = || format!("{}: {} at {}", path.display(), m.topic(), m.log_time);
        match m.topic() {
            TactileZeroed::TOPIC => {
                let z: TactileZeroed = serde_json::from_slice(&m.data).with_context(what)?;
                let scan = scan_of(&tactile.layout, &z.sensors).with_context(what)?;
                trace.estimates.push(stage.on_scan(m.log_time, &scan));
                trace.states.push(stage.reading().state);
                trace.times.push(m.log_time);
            }
            HandState::TOPIC => {
                let h: HandState = serde_json::from_slice(&m.data).with_context(what)?;
                stage.set_opening(h.opening);
            }
            _ => read_side(&mut side, m.topic(), m.log_time, &m.data).with_context(what)?,
        }
    }
    trace.marker_last_seen = side.marker_last_seen;
    if side.has_labels {
        trace.labels = Some(trace.times.iter().map(|t| at_or_before(&side.labels, *t)).collect());
        trace.robot_speed = (!side.robot_speed.is_empty())
            .then(|| trace.times.iter().map(|t| at_or_before(&side.robot_speed, *t)).collect());
    }
    Ok(trace)
}

/// Reads one message of a side channel (marker, label, robot).
fn read_side(side: &mut SideChannels, topic: &str, t: TimeNs, data: &[u8]) -> serde_json::Result<()> {
    match topic {
        ArucoDetection::TOPIC => {
            let seen = serde_json::from_slice::<ArucoDetection>(data)?.detected;
            if seen {
                side.marker_last_seen = Some(t);
            }
        }
        SLIP_TOPIC => side.labels.push((t, serde_json::from_slice::<SlipLabelMessage>(data)?.slip != 0.0)),
        _ if side.has_labels => {
            let v: CommandedVelocity = serde_json::from_slice(data)?;
            if let (Some(vx), Some(vy)) = (v.v_x_m_s, v.v_y_m_s) {
                side.robot_speed.push((t, vx.hypot(vy)));
            }
        }
        _ => {}
    }
    Ok(())
}

/// The ROC-AUC of the slip score and of the robot speed against the slip
/// label, over the rows (tactile scans) that have a label.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct SlipAuc {
    /// Rows with a label.
    pub rows: usize,
    /// Of them, rows labelled slip.
    pub slip_rows: usize,
    /// AUC of the slip score; `None` with one class only.
    pub auc_slip_score: Option<f64>,
    /// Rows with a label and a robot speed.
    pub speed_rows: usize,
    /// AUC of the robot speed on those rows; `None` with one class only or no speed.
    pub auc_robot_speed: Option<f64>,
}

/// Rows of a labelled session: `(score, speed, label)`.
type LabelledRow = (f64, Option<f64>, bool);

fn labelled_rows(trace: &SlipTrace) -> Option<Vec<LabelledRow>> {
    let labels = trace.labels.as_ref()?;
    let speed = |k: usize| trace.robot_speed.as_ref().and_then(|s| s[k]);
    let rows =
        labels.iter().enumerate().filter_map(|(k, l)| Some((trace.estimates[k].slip_score, speed(k), (*l)?)));
    Some(rows.collect())
}

impl SlipAuc {
    /// The AUCs over `rows`.
    fn of(rows: &[LabelledRow]) -> Result<SlipAuc> {
        let scores: Vec<f64> = rows.iter().map(|r| r.0).collect();
        let labels: Vec<bool> = rows.iter().map(|r| r.2).collect();
        let (speeds, speed_labels): (Vec<f64>, Vec<bool>) =
            rows.iter().filter_map(|r| Some((r.1?, r.2))).unzip();
        Ok(SlipAuc {
            rows: rows.len(),
            slip_rows: labels.iter().filter(|l| **l).count(),
            auc_slip_score: roc_auc(&scores, &labels)?,
            speed_rows: speeds.len(),
            auc_robot_speed: roc_auc(&speeds, &speed_labels)?,
        })
    }
}

/// One session's scores (times in s of log time).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SessionScores {
    /// The session file.
    pub file: String,
    /// Dropped according to the metadata; `None` when unknown.
    pub dropped: Option<bool>,
    /// Zeroed scans read.
    pub scans: usize,
    /// Largest load (counts).
    pub peak_load_counts: f64,
    /// Lowest `load / running peak` after the hold began (the contact level
    /// first reached), whatever the detector's state.
    pub lowest_load_ratio: Option<f64>,
    /// The tactile release (s).
    pub tactile_release_s: Option<f64>,
    /// The marker's last sighting (s).
    pub marker_last_seen_s: Option<f64>,
    /// The first Dropped reading (s).
    pub first_dropped_s: Option<f64>,
    /// `first_dropped_s - tactile_release_s` (s).
    pub delay_after_release_s: Option<f64>,
    /// `first_dropped_s - marker_last_seen_s` (s).
    pub delay_after_marker_s: Option<f64>,
    /// Entries into Dropped and Released, time held.
    pub hold: HoldSummary,
    /// Slip-label AUCs, where the session has labels.
    pub slip: Option<SlipAuc>,
}

/// The lowest `load / running peak` from the first load at or above
/// `contact` on.
fn lowest_load_ratio(loads: &[f64], contact: f64) -> Option<f64> {
    let start = loads.iter().position(|l| *l >= contact)?;
    let mut peak = f64::NEG_INFINITY;
    let ratios = loads[start..].iter().map(|l| {
        peak = peak.max(*l);
        l / peak
    });
    ratios.fold(None, |m: Option<f64>, r| Some(m.map_or(r, |m| m.min(r))))
}

impl SessionScores {
    /// Scores `trace` (run with `cfg`).
    pub fn of(trace: &SlipTrace, cfg: &GraspDetectorConfig) -> Result<SessionScores> {
        let times: Vec<f64> = trace.times.iter().map(|t| t.as_secs_f64()).collect();
        let loads: Vec<f64> = trace.estimates.iter().map(|e| e.load).collect();
        let release = tactile_release(&times, &loads, cfg)?;
        let first_dropped =
            times.iter().zip(&trace.states).find(|(_, s)| **s == GraspState::Dropped).map(|(t, _)| *t);
        let marker = trace.marker_last_seen.map(TimeNs::as_secs_f64);
        let delay_after_release = match release {
            Some(r) => drop_detection_delay_s(&times, &trace.states, r)?,
            None => None,
        };
        let slip = labelled_rows(trace).map(|rows| SlipAuc::of(&rows)).transpose()?;
        Ok(SessionScores {
            file: trace.path.display().to_string(),
            dropped: trace.dropped,
            scans: times.len(),
            peak_load_counts: loads.iter().copied().fold(0.0, f64::max),
            lowest_load_ratio: lowest_load_ratio(&loads, cfg.contact_load_counts),
            tactile_release_s: release,
            marker_last_seen_s: marker,
            first_dropped_s: first_dropped,
            delay_after_release_s: delay_after_release,
            delay_after_marker_s: first_dropped.zip(marker).map(|(d, m)| d - m),
            hold: hold_summary(&times, &trace.states)?,
            slip,
        })
    }
}

/// The scores over every session.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SlipSummary {
    /// Sessions read.
    pub sessions: usize,
    /// Sessions whose metadata says dropped.
    pub dropped_sessions: usize,
    /// Of them, those with a Dropped reading at all.
    pub drops_flagged: usize,
    /// Of them, those with a first Dropped reading within [`DROP_WINDOW_S`]
    /// of the tactile release.
    pub drops_detected: usize,
    /// The window (s).
    pub window_s: f64,
    /// Median of the detected drops' delays after the release (s).
    pub delay_median_s: Option<f64>,
    /// Largest of them (s).
    pub delay_max_s: Option<f64>,
    /// Median delay after the marker's last sighting (s), over the dropped
    /// sessions that read Dropped.
    pub delay_after_marker_median_s: Option<f64>,
    /// Smallest and largest of those delays (s).
    pub delay_after_marker_range_s: Option<[f64; 2]>,
    /// Sessions whose metadata says kept.
    pub kept_sessions: usize,
    /// Entries into Dropped on the kept sessions (false alarms).
    pub false_alarms: usize,
    /// Time held on the kept sessions (min).
    pub kept_held_min: f64,
    /// False alarms per minute held on the kept sessions.
    pub false_alarms_per_held_min: Option<f64>,
    /// The same per 5 minutes held.
    pub false_alarms_per_5_held_min: Option<f64>,
    /// Slip-label AUCs pooled over the labelled sessions' rows.
    pub slip: Option<SlipAuc>,
}

fn median(mut xs: Vec<f64>) -> Option<f64> {
    xs.sort_by(f64::total_cmp);
    let n = xs.len();
    match n {
        0 => None,
        _ if n % 2 == 1 => Some(xs[n / 2]),
        _ => Some((xs[n / 2 - 1] + xs[n / 2]) / 2.0),
    }
}

/// The smallest and largest of `xs`.
fn range(xs: &[f64]) -> Option<[f64; 2]> {
    xs.iter().fold(None, |r, x| Some(r.map_or([*x, *x], |[a, b]: [f64; 2]| [a.min(*x), b.max(*x)])))
}

impl SlipSummary {
    /// The summary of `scores`; `pooled` are the labelled rows of every session.
    fn of(scores: &[SessionScores], pooled: &[LabelledRow]) -> Result<SlipSummary> {
        let dropped: Vec<&SessionScores> = scores.iter().filter(|s| s.dropped == Some(true)).collect();
        let detected: Vec<&SessionScores> = dropped
            .iter()
            .copied()
            .filter(|s| s.delay_after_release_s.is_some_and(|d| d.abs() <= DROP_WINDOW_S))
            .collect();
        let after_marker: Vec<f64> = dropped.iter().filter_map(|s| s.delay_after_marker_s).collect();
        let mut kept = HoldSummary::default();
        let kept_sessions =
            scores.iter().filter(|s| s.dropped == Some(false)).inspect(|s| kept += s.hold).count();
        let per_min = kept.dropped_per_held_minute();
        Ok(SlipSummary {
            sessions: scores.len(),
            dropped_sessions: dropped.len(),
            drops_flagged: dropped.iter().filter(|s| s.first_dropped_s.is_some()).count(),
            drops_detected: detected.len(),
            window_s: DROP_WINDOW_S,
            delay_median_s: median(detected.iter().filter_map(|s| s.delay_after_release_s).collect()),
            delay_max_s: detected.iter().filter_map(|s| s.delay_after_release_s).reduce(f64::max),
            delay_after_marker_range_s: range(&after_marker),
            delay_after_marker_median_s: median(after_marker),
            kept_sessions,
            false_alarms: kept.dropped_entries,
            kept_held_min: kept.held_s / 60.0,
            false_alarms_per_held_min: per_min,
            false_alarms_per_5_held_min: per_min.map(|r| 5.0 * r),
            slip: (!pooled.is_empty()).then(|| SlipAuc::of(pooled)).transpose()?,
        })
    }
}

/// What `slidetrack slip` reports.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SlipReport {
    /// The detector's settings.
    pub detector: GraspDetectorConfig,
    /// The slip score's definition and unit.
    pub slip_score: String,
    /// Per session, in the order given.
    pub sessions: Vec<SessionScores>,
    /// Over all sessions.
    pub summary: SlipSummary,
}

/// Runs the stage with `cfg` over every file and scores it; an error names
/// the file that could not be read.
pub fn evaluate(files: &[PathBuf], cfg: GraspDetectorConfig) -> Result<SlipReport> {
    let mut sessions = Vec::with_capacity(files.len());
    let mut pooled = Vec::new();
    let mut slip_score = String::new();
    for path in files {
        let trace = run_offline(path, cfg).with_context(|| format!("cannot score {}", path.display()))?;
        slip_score = trace.metadata.get("slip_score").cloned().unwrap_or_default();
        pooled.extend(labelled_rows(&trace).unwrap_or_default());
        sessions.push(SessionScores::of(&trace, &cfg)?);
    }
    let summary = SlipSummary::of(&sessions, &pooled)?;
    Ok(SlipReport { detector: cfg, slip_score, sessions, summary })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_lowest_ratio_starts_at_contact_and_the_median_is_the_middle() {
        assert_eq!(lowest_load_ratio(&[0.0, 10.0, 100.0, 200.0, 50.0, 150.0], 100.0), Some(0.25));
        assert_eq!(lowest_load_ratio(&[0.0, 10.0], 100.0), None);
        assert_eq!(median(vec![3.0, 1.0, 2.0]), Some(2.0));
        assert_eq!(median(vec![4.0, 1.0, 2.0, 3.0]), Some(2.5));
        assert_eq!(median(Vec::new()), None);
        assert_eq!(range(&[0.1, -0.2, 0.05]), Some([-0.2, 0.1]));
        let series = [(TimeNs(10), 1), (TimeNs(20), 2)];
        assert_eq!(at_or_before(&series, TimeNs(5)), None);
        assert_eq!(at_or_before(&series, TimeNs(20)), Some(2));
        assert_eq!(at_or_before(&series, TimeNs(25)), Some(2));
    }
}
