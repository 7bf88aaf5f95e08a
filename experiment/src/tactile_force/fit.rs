//! Fits a rig's tactile force calibration on sessions with reference forces
//! and measures it, beside the trivial maps, on held-out sessions.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use serde::Serialize;
use slidetrack_calibration::tactile_force::{
    AxisErrors, FORMAT, ForceModelKind, SensorForceMap, TactileForceCalibration, TaxelForceMap, VERSION,
    axis_errors, fit_axis_slopes, fit_global_scale, fit_taxel,
};
use slidetrack_core::TactileLayout;

use super::data::{RecordedForces, recorded_forces};

/// What `calibrate tactile` fits and measures.
#[derive(Clone, Debug)]
pub struct TactileFitOptions {
    /// Sessions to fit on (tared counts and `/tactile/reference`).
    pub fit: Vec<PathBuf>,
    /// Held-out sessions to measure on (none: measured on the fit sessions).
    pub eval: Vec<PathBuf>,
    /// The terms of the map written.
    pub model: ForceModelKind,
    /// The calibration file to write.
    pub out: Option<PathBuf>,
    /// Replace `out` if it exists.
    pub overwrite: bool,
}

/// The errors of one map on the evaluation sessions.
#[derive(Clone, Debug, Serialize)]
pub struct MapErrors {
    /// The map (`zero`, `global scale`, `per-axis slope`, `linear`, `quadratic`).
    pub map: &'static str,
    /// Its errors per axis.
    pub errors: AxisErrors,
}

/// What `calibrate tactile` fitted and measured.
#[derive(Clone, Debug)]
pub struct TactileFitReport {
    /// The calibration (written to `out` when given).
    pub calibration: TactileForceCalibration,
    /// Scans fitted on.
    pub fit_scans: usize,
    /// Scans measured on.
    pub eval_scans: usize,
    /// True when the errors are on held-out sessions, false when on the fit sessions.
    pub held_out: bool,
    /// Scans left out of some taxel's fit as outliers (spikes).
    pub outliers: usize,
    /// The errors of each map, the trivial ones first.
    pub errors: Vec<MapErrors>,
}

/// Fits and measures; writes the calibration when `options.out` is given.
pub fn fit_tactile_calibration(options: &TactileFitOptions) -> Result<TactileFitReport> {
    if options.fit.is_empty() {
        bail!("no session to fit on");
    }
    if let Some(out) = options.out.as_ref().filter(|o| o.exists() && !options.overwrite) {
        bail!("{} already exists; pass --overwrite to replace it", out.display());
    }
    let fit = load_all(&options.fit)?;
    let eval = if options.eval.is_empty() { Vec::new() } else { load_all(&options.eval)? };
    let layout = same_layout(fit.iter().chain(&eval))?;
    let taxels = layout.taxel_count();
    let per_taxel = |data: &[RecordedForces], k: usize| -> (Vec<[f64; 3]>, Vec<[f64; 3]>) {
        let c = data.iter().flat_map(|d| d.counts.iter().map(move |s| s[k])).collect();
        let f = data.iter().flat_map(|d| d.force_n.iter().map(move |s| s[k])).collect();
        (c, f)
    };
    let mut maps = [Vec::new(), Vec::new()];
    let mut outliers = 0;
    for k in 0..taxels {
        let (c, f) = per_taxel(&fit, k);
        for (slot, kind) in maps.iter_mut().zip([ForceModelKind::Linear, ForceModelKind::Quadratic]) {
            let fitted = fit_taxel(kind, k, &c, &f).with_context(|| format!("fitting taxel {k}"))?;
            if kind == options.model {
                outliers += fitted.outliers;
            }
            slot.push(fitted.map);
        }
    }
    let chosen = if options.model == ForceModelKind::Linear { &maps[0] } else { &maps[1] };
    let all = |data: &[RecordedForces]| -> (Vec<[f64; 3]>, Vec<[f64; 3]>) {
        (0..taxels).map(|k| per_taxel(data, k)).fold((vec![], vec![]), |(mut c, mut f), (ck, fk)| {
            c.extend(ck);
            f.extend(fk);
            (c, f)
        })
    };
    let (fit_c, fit_f) = all(&fit);
    let fit_errors = per_taxel_errors(&fit, chosen);
    let calibration = calibration_file(&layout, options, chosen, &fit_errors);
    let held_out = !eval.is_empty();
    let measured = if held_out { &eval } else { &fit };
    let scale = fit_global_scale(&fit_c, &fit_f);
    let slopes = fit_axis_slopes(&fit_c, &fit_f);
    let (eval_c, eval_f) = all(measured);
    let pairs =
        |g: &dyn Fn([f64; 3]) -> [f64; 3]| axis_errors(eval_c.iter().zip(&eval_f).map(|(c, f)| (g(*c), *f)));
    let errors = vec![
        MapErrors { map: "zero", errors: pairs(&|_| [0.0; 3]) },
        MapErrors { map: "global scale", errors: pairs(&|c| c.map(|v| scale * v)) },
        MapErrors { map: "per-axis slope", errors: pairs(&|c| slopes.force_n(c)) },
        MapErrors { map: "linear", errors: per_taxel_errors(measured, &maps[0]) },
        MapErrors { map: "quadratic", errors: per_taxel_errors(measured, &maps[1]) },
    ];
    if let Some(out) = &options.out {
        calibration.save(out)?;
    }
    let scans = |d: &[RecordedForces]| -> usize { d.iter().map(|r| r.counts.len()).sum() };
    Ok(TactileFitReport {
        calibration,
        fit_scans: scans(&fit),
        eval_scans: scans(measured),
        held_out,
        outliers,
        errors,
    })
}

fn load_all(paths: &[PathBuf]) -> Result<Vec<RecordedForces>> {
    paths.iter().map(|p| recorded_forces(p)).collect()
}

/// The layout every session shares; an error names the first that differs.
fn same_layout<'a>(mut data: impl Iterator<Item = &'a RecordedForces>) -> Result<TactileLayout> {
    let first = data.next().context("no session")?;
    for d in data {
        if d.layout != first.layout {
            bail!("{} has another tactile layout than {}", d.path.display(), first.path.display());
        }
    }
    Ok(first.layout.clone())
}

/// The errors of per-taxel `maps` on every scan of `data`.
fn per_taxel_errors(data: &[RecordedForces], maps: &[TaxelForceMap]) -> AxisErrors {
    let pairs = data.iter().flat_map(move |d| {
        d.counts
            .iter()
            .zip(&d.force_n)
            .flat_map(move |(c, f)| maps.iter().zip(c.iter().zip(f)).map(|(m, (c, f))| (m.force_n(*c), *f)))
    });
    axis_errors(pairs)
}

/// The calibration file of `maps` (layout order) for `layout`.
fn calibration_file(
    layout: &TactileLayout,
    options: &TactileFitOptions,
    maps: &[TaxelForceMap],
    fit_errors: &AxisErrors,
) -> TactileForceCalibration {
    let mut maps = maps.iter().cloned();
    let sensors = layout
        .sensors
        .iter()
        .map(|s| SensorForceMap { name: s.name.clone(), taxels: maps.by_ref().take(s.taxels()).collect() })
        .collect();
    TactileForceCalibration {
        format: FORMAT.into(),
        version: VERSION,
        model: options.model,
        baseline: "tare: counts minus the mean of the open-hand scans (/tactile/zeroed)".into(),
        reference: "/tactile/reference".into(),
        fitted_on: options.fit.iter().map(|p| file_name(p)).collect(),
        fit_rms_n: fit_errors.rms_n,
        fit_range_n: fit_errors.range_n,
        sensors,
    }
}

fn file_name(path: &Path) -> String {
    path.file_name().map_or_else(|| path.display().to_string(), |n| n.to_string_lossy().into_owned())
}
