//! Tared counts and reference forces of a session, scan by scan.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use slidetrack_core::{TactileLayout, TimeNs};
use slidetrack_session::{
    ReadOptions, SessionInfo, TactileRaw, TactileReference, TactileZeroed, read_channel, scan_of,
};

use crate::channels::recorded_tactile;

/// Scans at the start of a session without `/tactile/zeroed` (a `record`
/// session) whose mean is the baseline: the taxels must be free then.
pub const BASELINE_SCANS: usize = 50;

/// One tared scan: session time, scan counter and counts minus baseline of
/// every taxel in layout order.
#[derive(Clone, Debug, PartialEq)]
pub struct TaredScan {
    /// Log time of the scan.
    pub t: TimeNs,
    /// The scan counter of `/tactile/raw`.
    pub sequence: u64,
    /// Counts minus baseline `[x, y, z]` per taxel.
    pub counts: Vec<[f64; 3]>,
}

/// The tactile layout of the session at `path`.
pub fn session_layout(path: &Path) -> Result<TactileLayout> {
    let info = SessionInfo::read(path, ReadOptions::default())?;
    let tactile = recorded_tactile(path, &info)?
        .with_context(|| format!("{}: no /tactile/raw channel with a taxel layout", path.display()))?;
    Ok(tactile.layout)
}

/// Every tared scan of the session at `path`: its `/tactile/zeroed` (the
/// protocol's tare, taken with the hand open), or without that channel its
/// `/tactile/raw` minus the mean of the first [`BASELINE_SCANS`] scans.
pub fn tared_scans(path: &Path, layout: &TactileLayout) -> Result<Vec<TaredScan>> {
    let at = |what: &str| format!("{}: {what}", path.display());
    let raw = read_channel::<TactileRaw>(path, ReadOptions::default())?;
    let sequences: BTreeMap<TimeNs, u64> = raw.iter().map(|(t, m)| (*t, m.sequence)).collect();
    let info = SessionInfo::read(path, ReadOptions::default())?;
    if info.channel("/tactile/zeroed").is_some() {
        let zeroed = read_channel::<TactileZeroed>(path, ReadOptions::default())?;
        return zeroed
            .into_iter()
            .map(|(t, m)| {
                let counts = scan_of(layout, &m.sensors).with_context(|| at("/tactile/zeroed"))?;
                Ok(TaredScan { t, sequence: sequences.get(&t).copied().unwrap_or(0), counts })
            })
            .collect();
    }
    if raw.len() <= BASELINE_SCANS {
        bail!("{}", at(&format!("{} scans; the baseline alone takes {BASELINE_SCANS}", raw.len())));
    }
    let scans: Vec<(TimeNs, u64, Vec<[f64; 3]>)> = raw
        .into_iter()
        .map(|(t, m)| {
            let scan = m.scan(layout).with_context(|| at("/tactile/raw"))?;
            Ok((t, m.sequence, scan.iter().map(|c| c.map(f64::from)).collect()))
        })
        .collect::<Result<_>>()?;
    let mut baseline = vec![[0.0; 3]; layout.taxel_count()];
    for (_, _, scan) in &scans[..BASELINE_SCANS] {
        for (b, c) in baseline.iter_mut().zip(scan) {
            for (b, c) in b.iter_mut().zip(c) {
                *b += c / BASELINE_SCANS as f64;
            }
        }
    }
    Ok(scans
        .into_iter()
        .map(|(t, sequence, scan)| {
            let counts = scan.iter().zip(&baseline).map(|(c, b)| [0, 1, 2].map(|i| c[i] - b[i])).collect();
            TaredScan { t, sequence, counts }
        })
        .collect())
}

/// A session's tared counts paired with its reference forces, scan by scan.
#[derive(Clone, Debug, PartialEq)]
pub struct RecordedForces {
    /// The session.
    pub path: PathBuf,
    /// Its tactile layout.
    pub layout: TactileLayout,
    /// Tared counts per scan, per taxel (layout order).
    pub counts: Vec<Vec<[f64; 3]>>,
    /// Reference force (N) per scan, per taxel.
    pub force_n: Vec<Vec<[f64; 3]>>,
}

/// The tared scans of `path` that have a `/tactile/reference` message at
/// the same log time, with their reference.
pub fn recorded_forces(path: &Path) -> Result<RecordedForces> {
    let layout = session_layout(path)?;
    let reference = read_channel::<TactileReference>(path, ReadOptions::default()).with_context(|| {
        format!(
            "{}: no reference forces to fit to (record the simulated rig with [sim] reference_forces = true, \
             or add /tactile/reference from a force sensor)",
            path.display()
        )
    })?;
    let reference: BTreeMap<TimeNs, Vec<[f64; 3]>> = reference
        .into_iter()
        .map(|(t, m)| {
            let scan = scan_of(&layout, &m.sensors)
                .with_context(|| format!("{}: /tactile/reference", path.display()))?;
            Ok((t, scan))
        })
        .collect::<Result<_>>()?;
    let mut out =
        RecordedForces { path: path.to_path_buf(), layout: layout.clone(), counts: vec![], force_n: vec![] };
    for scan in tared_scans(path, &layout)? {
        if let Some(f) = reference.get(&scan.t) {
            out.counts.push(scan.counts);
            out.force_n.push(f.clone());
        }
    }
    if out.counts.is_empty() {
        bail!("{}: no tared scan has a reference force at its time", path.display());
    }
    Ok(out)
}
