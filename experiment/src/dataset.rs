//! Sessions as dEKF data: baseline-subtracted tactile channels, the ground
//! truth at the same scans, cut at the release.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use serde::Deserialize;

use crate::channels::recorded_tactile;
use slidetrack_calibration::label::GroundTruthSlot;
use slidetrack_core::{TactileInfo, TimeNs};
use slidetrack_estimators::dekf::StateKind;
use slidetrack_session::{
    ChannelMessage, GroundTruthPlanar, MessageReader, PlanarState, ProtocolEvent, ReadOptions, SessionInfo,
    TactileRaw, TactileZeroed, scan_of,
};

/// Topic of the ground truth written by `slidetrack label`.
pub const GROUND_TRUTH_TOPIC: &str = "/ground_truth/sliding";
/// Topic of the simulator's truth.
pub const SIM_TRUTH_TOPIC: &str = "/sim/truth";

/// A channel set of Table 6.2.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum ChannelSet {
    /// x, y and z of every finger.
    Xyz,
    /// x and y (the shear channels) of every finger.
    Xy,
    /// z (the normal channel) of every finger.
    Z,
}

impl ChannelSet {
    /// Channel names in model input order.
    pub fn names(self) -> Vec<String> {
        let axes: &[&str] = match self {
            ChannelSet::Xyz => &["x", "y", "z"],
            ChannelSet::Xy => &["x", "y"],
            ChannelSet::Z => &["z"],
        };
        crate::channels::finger_channels(axes)
    }

    /// The set whose channels are `names`, if any.
    pub fn named(names: &[String]) -> Option<ChannelSet> {
        [ChannelSet::Xyz, ChannelSet::Xy, ChannelSet::Z].into_iter().find(|s| s.names() == names)
    }

    /// The channels of `text`: a set's name (`xyz`, `xy`, `z`), or channel
    /// names separated by commas (`thumb.5.z,index.mean.x`).
    pub fn parse_channels(text: &str) -> Vec<String> {
        match text {
            "xyz" => ChannelSet::Xyz.names(),
            "xy" => ChannelSet::Xy.names(),
            "z" => ChannelSet::Z.names(),
            _ => text.split(',').map(|c| c.trim().to_string()).filter(|c| !c.is_empty()).collect(),
        }
    }

    /// `xyz`, `xy` or `z`.
    pub fn name(self) -> &'static str {
        match self {
            ChannelSet::Xyz => "xyz",
            ChannelSet::Xy => "xy",
            ChannelSet::Z => "z",
        }
    }
}

/// Topic of the ground truth of the thesis protocol, written by
/// `slidetrack label --thesis --slot thesis` beside [`GROUND_TRUTH_TOPIC`].
pub const THESIS_GROUND_TRUTH_TOPIC: &str = GroundTruthSlot::Thesis.sliding_topic();

/// Which truth to train and score against.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TruthSource {
    /// `/ground_truth/planar` from `slidetrack label`: the object's motion in
    /// the contact plane during the hold (the truth of planar models).
    Planar,
    /// `/ground_truth/sliding` from `slidetrack label` (the marker smoothed
    /// as thesis Sec. 6.2.3 describes, with this project's parameters).
    GroundTruth,
    /// `/ground_truth/thesis/sliding` from `slidetrack label --thesis --slot
    /// thesis`: the same smoother with the thesis's parameters.
    ThesisGroundTruth,
    /// `/sim/truth`, the simulator's own (simulated sessions only).
    Sim,
}

impl TruthSource {
    /// The topic it reads.
    pub fn topic(self) -> &'static str {
        match self {
            TruthSource::Planar => GroundTruthPlanar::TOPIC,
            TruthSource::GroundTruth => GROUND_TRUTH_TOPIC,
            TruthSource::ThesisGroundTruth => THESIS_GROUND_TRUTH_TOPIC,
            TruthSource::Sim => SIM_TRUTH_TOPIC,
        }
    }

    /// A ground truth of `slidetrack label` (from the marker), not the simulator's.
    pub fn is_labelled(self) -> bool {
        self != TruthSource::Sim
    }

    /// Components of one truth sample: `(p, v)` along the sliding axis, or
    /// the planar state `(x, y, theta, vx, vy, omega)`.
    pub fn dim(self) -> usize {
        if self == TruthSource::Planar { 6 } else { 2 }
    }

    /// The truth of models of `state`: `/ground_truth/planar` for planar
    /// models, else `self`.
    pub fn for_state(self, state: StateKind) -> TruthSource {
        match state {
            StateKind::Planar => TruthSource::Planar,
            StateKind::Sliding => self,
        }
    }
}

#[derive(Deserialize)]
struct PositionVelocity {
    position: f64,
    velocity: f64,
}

/// One truth sample in SI units: `(p, v)` (m, m/s) or the planar state
/// `(x, y, theta, vx, vy, omega)` (m, m, rad, m/s, m/s, rad/s).
fn truth_values(source: TruthSource, data: &[u8]) -> serde_json::Result<Vec<f64>> {
    if source == TruthSource::Planar {
        let PlanarState {
            translation_m: [x, y],
            rotation_rad,
            velocity_m_per_s: [vx, vy],
            angular_velocity_rad_per_s,
        } = serde_json::from_slice::<GroundTruthPlanar>(data)?.0;
        Ok(vec![x, y, rotation_rad, vx, vy, angular_velocity_rad_per_s])
    } else {
        let r: PositionVelocity = serde_json::from_slice(data)?;
        Ok(vec![r.position, r.velocity])
    }
}

/// Fewest tactile scans a session must have to be trained or scored on.
pub const MIN_SCANS: usize = 10;

/// A session with fewer than [`MIN_SCANS`] scans to use: before the
/// release, or in the hold (planar truth; a grasp lost at once).
#[derive(Debug, thiserror::Error)]
#[error("{}: only {scans} tactile scans {what}", path.display())]
pub struct TooFewScans {
    /// The file.
    pub path: PathBuf,
    /// The scans it has.
    pub scans: usize,
    /// Where they were counted.
    pub what: &'static str,
}

/// [`load`], but `Ok(None)` for a session with too few scans
/// ([`TooFewScans`]): training and scoring many sessions skip it (and say so).
pub fn load_unless_short(path: &Path, truth: Option<TruthSource>) -> Result<Option<SessionData>> {
    match load(path, truth) {
        Ok(d) => Ok(Some(d)),
        Err(e) if e.is::<TooFewScans>() => Ok(None),
        Err(e) => Err(e),
    }
}

/// One session's data at the tactile rate, from the first baseline-subtracted
/// scan to the release.
#[derive(Clone, Debug)]
pub struct SessionData {
    /// The file.
    pub path: PathBuf,
    /// Scan times.
    pub times: Vec<TimeNs>,
    /// The tactile source that recorded it (from the `/tactile/raw` layout).
    pub tactile: TactileInfo,
    /// Baseline-subtracted values of every taxel of every scan (counts),
    /// scan after scan, `tactile.layout.taxel_count()` taxels each.
    pub zeroed: Vec<[f64; 3]>,
    /// Truth per scan, [`TruthSource::dim`] components each in SI units
    /// (`(p, v)` in m and m/s; planar: m, rad, m/s, rad/s), scan after
    /// scan, when the session has it; NaN at the scans of the hold the
    /// planar truth leaves out (marker gaps).
    pub truth: Option<Vec<f64>>,
    /// Components of one truth sample.
    pub truth_dim: usize,
    /// The tactile scan rate (Hz), from the scan times.
    pub rate_hz: f64,
}

/// The recorded channels [`load`] reads, in one pass over the file.
#[derive(Default)]
struct Recorded {
    release: Option<TimeNs>,
    tactile: Option<TactileInfo>,
    times: Vec<TimeNs>,
    zeroed: Vec<[f64; 3]>,
    truth: Vec<(TimeNs, Vec<f64>)>,
}

/// Reads the protocol events, the zeroed scans and `truth_topic` of `path`
/// in one pass.
fn read_recorded(path: &Path, truth: Option<TruthSource>) -> Result<(Recorded, Vec<String>)> {
    let mut topics = vec![ProtocolEvent::TOPIC, TactileZeroed::TOPIC];
    topics.extend(truth.map(TruthSource::topic));
    let mut reader = MessageReader::open(path, &topics, ReadOptions::default())?;
    let info = SessionInfo::read(path, ReadOptions::default())?;
    let mut out = Recorded { tactile: recorded_tactile(path, &info)?, ..Recorded::default() };
    for message in reader.by_ref() {
        let m = message?;
        let t = m.log_time;
        let what = || format!("{}: {} at {t}", path.display(), m.topic());
        match m.topic() {
            ProtocolEvent::TOPIC => {
                let event: ProtocolEvent = serde_json::from_slice(&m.data).with_context(what)?;
                if out.release.is_none() && event.ends_cycles() {
                    out.release = Some(t);
                }
            }
            TactileZeroed::TOPIC => {
                let z: TactileZeroed = serde_json::from_slice(&m.data).with_context(what)?;
                let layout = &out.tactile.as_ref().with_context(what)?.layout;
                out.zeroed.extend(scan_of(layout, &z.sensors).with_context(what)?);
                out.times.push(t);
            }
            _ => {
                let source = truth.with_context(what)?;
                out.truth.push((t, truth_values(source, &m.data).with_context(what)?));
            }
        }
    }
    let declared = reader.channels().map(|c| c.topic.clone()).collect();
    Ok((out, declared))
}

/// Reads a session; `truth` names the truth to attach (an error when the
/// session lacks it), or `None` for none. The scans run from the first
/// baseline-subtracted one to the release; with the planar truth, which
/// covers the hold only, they are cut to the scans it covers.
pub fn load(path: &Path, truth: Option<TruthSource>) -> Result<SessionData> {
    let (recorded, declared) = read_recorded(path, truth)?;
    if !declared.iter().any(|t| t == TactileZeroed::TOPIC) {
        bail!("{}: no baseline-subtracted tactile data ({})", path.display(), TactileZeroed::TOPIC);
    }
    let tactile =
        recorded.tactile.with_context(|| format!("{}: no {}", path.display(), TactileRaw::TOPIC))?;
    let end = recorded.release.unwrap_or(TimeNs(u64::MAX));
    let mut first = 0;
    let mut scans = recorded.times.iter().take_while(|t| **t < end).count();
    if let Some(TruthSource::Planar) = truth {
        // The hold: the scans the planar truth covers.
        let span = recorded.truth.first().zip(recorded.truth.last()).map(|(a, b)| (a.0, b.0));
        let (from, to) =
            span.with_context(|| format!("{}: {} is empty", path.display(), GroundTruthPlanar::TOPIC))?;
        first = recorded.times.iter().take_while(|t| **t < from).count();
        scans = scans.min(recorded.times.iter().take_while(|t| **t <= to).count());
    }
    if scans < first + MIN_SCANS {
        let what = if truth == Some(TruthSource::Planar) { "in the hold" } else { "before the release" };
        return Err(TooFewScans { path: path.to_path_buf(), scans: scans.saturating_sub(first), what }.into());
    }
    let times = recorded.times[first..scans].to_vec();
    let n = tactile.layout.taxel_count();
    let values = recorded.zeroed[first * n..scans * n].to_vec();
    let span_s = times[times.len() - 1].secs_since(times[0]);
    let rate_hz = (times.len() - 1) as f64 / span_s.max(1e-9);
    let truth_values = match truth {
        None => None,
        Some(source) => {
            if !declared.iter().any(|t| t == source.topic()) {
                let hint = match source {
                    TruthSource::GroundTruth | TruthSource::Planar => "; run `slidetrack label` on it first",
                    TruthSource::ThesisGroundTruth => {
                        "; run `slidetrack label --thesis --slot thesis` on it first"
                    }
                    TruthSource::Sim => "",
                };
                bail!("{} has no {}{hint}", path.display(), source.topic());
            }
            let by_time: std::collections::HashMap<u64, &Vec<f64>> =
                recorded.truth.iter().map(|(t, r)| (t.0, r)).collect();
            let mut flat = Vec::with_capacity(times.len() * source.dim());
            for t in &times {
                match by_time.get(&t.0) {
                    Some(v) => flat.extend_from_slice(v),
                    // The planar truth leaves out scans where the marker
                    // was not seen for long: no truth there.
                    None if source == TruthSource::Planar => flat.extend([f64::NAN; 6]),
                    None => bail!("{}: {} does not cover every tactile scan", path.display(), source.topic()),
                }
            }
            Some(flat)
        }
    };
    Ok(SessionData {
        path: path.to_path_buf(),
        times,
        tactile,
        zeroed: values,
        truth: truth_values,
        truth_dim: truth.map_or(0, TruthSource::dim),
        rate_hz,
    })
}

impl SessionData {
    /// The truth at scan `k`, when the session has it.
    pub fn truth_at(&self, k: usize) -> Option<&[f64]> {
        self.truth.as_ref().map(|t| &t[k * self.truth_dim..(k + 1) * self.truth_dim])
    }

    /// The baseline-subtracted taxels of every scan, in scan order.
    pub fn scans(&self) -> std::slice::ChunksExact<'_, [f64; 3]> {
        self.zeroed.chunks_exact(self.tactile.layout.taxel_count().max(1))
    }
}

/// The `.mcap` files named, directories expanded (sorted).
pub fn expand(paths: &[PathBuf]) -> Result<Vec<PathBuf>> {
    let mut out = Vec::new();
    for p in paths {
        if p.is_dir() {
            let mut files: Vec<PathBuf> = std::fs::read_dir(p)
                .with_context(|| format!("cannot list {}", p.display()))?
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|f| f.extension().is_some_and(|e| e == "mcap"))
                .collect();
            files.sort();
            out.extend(files);
        } else {
            out.push(p.clone());
        }
    }
    if out.is_empty() {
        bail!(
            "no session files (.mcap) in {}",
            paths.iter().map(|p| p.display().to_string()).collect::<Vec<_>>().join(", ")
        );
    }
    Ok(out)
}
