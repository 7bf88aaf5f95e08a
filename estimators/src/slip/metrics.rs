//! Scores of the detector against offline references: the tactile release
//! time, the delay of drop detection, false alarms per minute of holding, and
//! the ROC of a score that should separate two classes.

use std::ops::AddAssign;

use serde::Serialize;

use super::detector::{GraspDetectorConfig, GraspState};
use super::error::GraspError;

/// The reference release is where the load falls below this fraction of its
/// level just before, for good.
pub const REFERENCE_RELEASE_FRACTION: f64 = 0.5;

/// The load's level before a candidate release: its median over this long (s).
pub const REFERENCE_LEVEL_WINDOW_S: f64 = 1.0;

fn same_length(what: &'static str, left: usize, right: usize) -> Result<(), GraspError> {
    if left == right { Ok(()) } else { Err(GraspError::LengthMismatch { what, left, right }) }
}

/// The median of `values` (not empty), sorting them.
fn median(values: &mut [f64]) -> f64 {
    values.sort_by(f64::total_cmp);
    let n = values.len();
    if n % 2 == 1 { values[n / 2] } else { 0.5 * (values[n / 2 - 1] + values[n / 2]) }
}

/// The offline release time of one grasp (s): the first sample after which
/// the load stays below [`REFERENCE_RELEASE_FRACTION`] of its level in the
/// second before, to the end of the trace: the final collapse.
///
/// Precisely: the hold begins at the first sample `h` whose load reaches
/// `cfg.contact_load_counts`; for a sample `k > h`, its level `l(k)` is the
/// median load of the samples in `[t_k - 1 s, t_k)` from `h` on; the
/// release is `times_s[k]` for the smallest such `k` with `L(j) < 0.5 l(k)`
/// for every `j >= k`. A dip that rises back is not a release, and neither
/// is a slow relaxation of the grasp: the level follows it, and only the
/// abrupt loss at the end falls below half of it. (A reference against the
/// running peak, as the detector's drop rule uses, marks such a relaxation
/// seconds before the fall on 6 of the 14 xela-imanlab drops.) `None` when
/// there is no contact or the load never collapses. Samples whose time or
/// load is not finite are skipped. `times_s` (s) and `loads_counts`
/// (counts) must have the same length.
pub fn tactile_release(
    times_s: &[f64],
    loads_counts: &[f64],
    cfg: &GraspDetectorConfig,
) -> Result<Option<f64>, GraspError> {
    same_length("tactile_release times against loads", times_s.len(), loads_counts.len())?;
    let samples: Vec<(f64, f64)> = times_s
        .iter()
        .zip(loads_counts)
        .filter(|(t, l)| t.is_finite() && l.is_finite())
        .map(|(t, l)| (*t, *l))
        .collect();
    let Some(h) = samples.iter().position(|(_, l)| *l >= cfg.contact_load_counts) else { return Ok(None) };
    // The largest load from each sample to the end.
    let mut suffix_max = vec![f64::NEG_INFINITY; samples.len() + 1];
    for k in (0..samples.len()).rev() {
        suffix_max[k] = suffix_max[k + 1].max(samples[k].1);
    }
    let mut window = Vec::new();
    for k in h + 1..samples.len() {
        let t = samples[k].0;
        window.clear();
        window.extend(
            samples[h..k].iter().filter(|(s, _)| *s >= t - REFERENCE_LEVEL_WINDOW_S).map(|(_, l)| *l),
        );
        if window.is_empty() {
            continue;
        }
        if suffix_max[k] < REFERENCE_RELEASE_FRACTION * median(&mut window) {
            return Ok(Some(t));
        }
    }
    Ok(None)
}

/// How late the detector saw the drop (s): the time of the first
/// [`GraspState::Dropped`] minus `release_t_s` (s, e.g. from
/// [`tactile_release`]); negative when it came before the reference.
/// `None` when the detector never reported Dropped. `times_s` (s) and
/// `states` are the detector's readings, in order.
pub fn drop_detection_delay_s(
    times_s: &[f64],
    states: &[GraspState],
    release_t_s: f64,
) -> Result<Option<f64>, GraspError> {
    same_length("drop_detection_delay_s times against states", times_s.len(), states.len())?;
    let first = times_s.iter().zip(states).find(|(_, s)| **s == GraspState::Dropped);
    Ok(first.map(|(t, _)| t - release_t_s))
}

/// Entries into the end states and the time held, over one or more
/// sequences (add them with `+=`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct HoldSummary {
    /// Times the state became Dropped: false alarms on a sequence that was
    /// not dropped.
    pub dropped_entries: usize,
    /// Times the state became Released.
    pub released_entries: usize,
    /// Time spent in Holding or Slipping (s): each reading counts until the
    /// next one.
    pub held_s: f64,
}

impl HoldSummary {
    /// Dropped entries per minute held (1/min); `None` before any holding.
    pub fn dropped_per_held_minute(&self) -> Option<f64> {
        (self.held_s > 0.0).then(|| self.dropped_entries as f64 / (self.held_s / 60.0))
    }
}

impl AddAssign for HoldSummary {
    fn add_assign(&mut self, other: HoldSummary) {
        self.dropped_entries += other.dropped_entries;
        self.released_entries += other.released_entries;
        self.held_s += other.held_s;
    }
}

/// Counts the entries into Dropped and Released and the time held in one
/// sequence of readings: `times_s` (s) and `states` in order, same length.
/// A step whose time difference is not finite or negative adds no time.
pub fn hold_summary(times_s: &[f64], states: &[GraspState]) -> Result<HoldSummary, GraspError> {
    same_length("hold_summary times against states", times_s.len(), states.len())?;
    let mut summary = HoldSummary::default();
    let mut previous: Option<GraspState> = None;
    for (i, &state) in states.iter().enumerate() {
        if previous != Some(state) {
            match state {
                GraspState::Dropped => summary.dropped_entries += 1,
                GraspState::Released => summary.released_entries += 1,
                _ => {}
            }
        }
        previous = Some(state);
        if state.is_held() {
            let dt_s = times_s.get(i + 1).map_or(0.0, |next| next - times_s[i]);
            if dt_s.is_finite() && dt_s > 0.0 {
                summary.held_s += dt_s;
            }
        }
    }
    Ok(summary)
}

/// Checks the inputs of the ROC functions; returns the class sizes
/// `(positives, negatives)`.
fn roc_inputs(scores: &[f64], labels: &[bool]) -> Result<(usize, usize), GraspError> {
    same_length("roc scores against labels", scores.len(), labels.len())?;
    if let Some(index) = scores.iter().position(|s| s.is_nan()) {
        return Err(GraspError::NanScore { index });
    }
    let positives = labels.iter().filter(|&&l| l).count();
    Ok((positives, labels.len() - positives))
}

/// The area under the ROC curve: the probability that a positive
/// (`labels[i] == true`) scores higher than a negative, ties counted half
/// (the Mann-Whitney U over `positives * negatives`). 1 when every positive
/// scores above every negative, 0 when below. `None` when only one class is
/// present; an error for a NaN score or lengths that differ.
pub fn roc_auc(scores: &[f64], labels: &[bool]) -> Result<Option<f64>, GraspError> {
    let (positives, negatives) = roc_inputs(scores, labels)?;
    if positives == 0 || negatives == 0 {
        return Ok(None);
    }
    let mut order: Vec<usize> = (0..scores.len()).collect();
    // Ties are runs of `==` scores: -0 and 0 sort next to each other.
    order.sort_by(|&a, &b| scores[a].total_cmp(&scores[b]));
    // Sum of the (1-based, tie-averaged) ranks of the positives.
    let mut rank_sum = 0.0;
    let mut start = 0;
    while start < order.len() {
        let score = scores[order[start]];
        let end = start + order[start..].iter().take_while(|&&i| scores[i] == score).count();
        let mean_rank = (start + 1 + end) as f64 / 2.0;
        rank_sum += mean_rank * order[start..end].iter().filter(|&&i| labels[i]).count() as f64;
        start = end;
    }
    let p = positives as f64;
    let u = rank_sum - p * (p + 1.0) / 2.0;
    Ok(Some(u / (p * negatives as f64)))
}

/// A ROC curve: point `i` calls positive every score `>= thresholds[i]`.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct RocCurve {
    /// Decision thresholds (score unit), decreasing; the first is `+inf`
    /// (nothing called positive).
    pub thresholds: Vec<f64>,
    /// True-positive rate at each threshold (fraction of positives).
    pub tpr: Vec<f64>,
    /// False-positive rate at each threshold (fraction of negatives).
    pub fpr: Vec<f64>,
}

impl RocCurve {
    /// The trapezoidal area under the curve; equals [`roc_auc`].
    pub fn area(&self) -> f64 {
        let points = self.fpr.iter().zip(&self.tpr);
        points.clone().zip(points.skip(1)).map(|((x0, y0), (x1, y1))| (x1 - x0) * (y0 + y1) / 2.0).sum()
    }
}

/// The ROC curve, one point per distinct score (from `(0, 0)` at `+inf` to
/// `(1, 1)` at the lowest score). `None` when only one class is present;
/// an error for a NaN score or lengths that differ.
pub fn roc_curve(scores: &[f64], labels: &[bool]) -> Result<Option<RocCurve>, GraspError> {
    let (positives, negatives) = roc_inputs(scores, labels)?;
    if positives == 0 || negatives == 0 {
        return Ok(None);
    }
    let mut order: Vec<usize> = (0..scores.len()).collect();
    order.sort_by(|&a, &b| scores[b].total_cmp(&scores[a]));
    let mut curve = RocCurve { thresholds: vec![f64::INFINITY], tpr: vec![0.0], fpr: vec![0.0] };
    let (mut tp, mut fp) = (0usize, 0usize);
    for (k, &i) in order.iter().enumerate() {
        if labels[i] {
            tp += 1;
        } else {
            fp += 1;
        }
        let last_of_tie = order.get(k + 1).is_none_or(|&next| scores[next] != scores[i]);
        if last_of_tie {
            curve.thresholds.push(scores[i]);
            curve.tpr.push(tp as f64 / positives as f64);
            curve.fpr.push(fp as f64 / negatives as f64);
        }
    }
    Ok(Some(curve))
}
