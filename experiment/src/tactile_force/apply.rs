//! Adds `/tactile/calibrated` to a finished session: its tared counts
//! through a calibration file.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use slidetrack_calibration::tactile_force::TactileForceCalibration;
use slidetrack_session::{
    NewChannel, NewMessage, ReadOptions, TactileCalibrated, rewrite_session, sensor_taxels,
};

use super::data::{session_layout, tared_scans};

/// What `calibrate tactile --apply` reads and writes.
#[derive(Clone, Debug)]
pub struct TactileApplyOptions {
    /// The session.
    pub session: PathBuf,
    /// The calibration file.
    pub calibration: PathBuf,
    /// The copy to write, with `/tactile/calibrated`.
    pub out: PathBuf,
    /// Replace `out` if it exists.
    pub overwrite: bool,
}

/// Reads a calibration file; an error names it.
pub fn load_calibration(path: &Path) -> Result<TactileForceCalibration> {
    // The error names the file.
    TactileForceCalibration::load(path).context("invalid tactile calibration")
}

/// Writes a copy of the session with `/tactile/calibrated` (replacing a
/// device's own forces, if it had them); returns the number of scans.
pub fn apply_tactile_calibration(options: &TactileApplyOptions) -> Result<usize> {
    if options.out.exists() && !options.overwrite {
        bail!("{} already exists; pass --overwrite to replace it", options.out.display());
    }
    if std::fs::canonicalize(&options.session).ok() == std::fs::canonicalize(&options.out).ok() {
        bail!("--out must differ from the input session");
    }
    let calibration = load_calibration(&options.calibration)?;
    let layout = session_layout(&options.session)?;
    calibration.check_layout(&layout).with_context(|| options.session.display().to_string())?;
    let mut channel = NewChannel::of::<TactileCalibrated>(Default::default());
    let scans = tared_scans(&options.session, &layout)?;
    for scan in &scans {
        let forces = calibration.forces_n(&scan.counts);
        let msg = TactileCalibrated { sequence: scan.sequence, sensors: sensor_taxels(&layout, &forces) };
        // The MCAP sequence as the recorder writes it: the scan counter's low 32 bits.
        let sequence = (scan.sequence & u64::from(u32::MAX)) as u32;
        let data = serde_json::to_vec(&msg)?;
        channel.messages.push(NewMessage { log_time: scan.t, publish_time: scan.t, sequence, data });
    }
    let tmp = options.out.with_extension("mcap.partial");
    std::fs::copy(&options.session, &tmp)
        .with_context(|| format!("cannot copy {} to {}", options.session.display(), tmp.display()))?;
    if let Err(e) = rewrite_session(&tmp, ReadOptions::default(), &|_| false, vec![channel]) {
        let _ = std::fs::remove_file(&tmp);
        return Err(e.into());
    }
    std::fs::rename(&tmp, &options.out).with_context(|| format!("cannot write {}", options.out.display()))?;
    Ok(scans.len())
}
