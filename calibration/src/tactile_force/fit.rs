//! Least-squares fit of one taxel's map from tared counts to force.

use nalgebra::DMatrix;

use super::error::TactileForceError;
use super::features::{ForceModelKind, TaxelForceMap};

/// Scans whose residual is above this many times the residuals' RMS are
/// left out of a second fit (the sensor's rare spikes).
const OUTLIER_FACTOR: f64 = 6.0;

/// Singular values below this fraction of the largest (columns scaled to
/// unit RMS) count as missing: the term is not determined by the data.
const RANK_TOLERANCE: f64 = 1e-9;

/// A fitted taxel map and how well it fits its own data.
#[derive(Clone, Debug, PartialEq)]
pub struct TaxelFit {
    /// The map.
    pub map: TaxelForceMap,
    /// Scans left out of the final fit as outliers (spikes).
    pub outliers: usize,
    /// RMS error per axis on the scans kept (N).
    pub rms_n: [f64; 3],
}

/// Fits the map of taxel `taxel` (its index, for messages) from its tared
/// `counts` to the reference `force_n` (N), scan by scan, by least squares
/// per axis; then once more without the scans whose error is above
/// [`OUTLIER_FACTOR`] times the RMS.
pub fn fit_taxel(
    kind: ForceModelKind,
    taxel: usize,
    counts: &[[f64; 3]],
    force_n: &[[f64; 3]],
) -> Result<TaxelFit, TactileForceError> {
    if counts.len() != force_n.len() {
        return Err(TactileForceError::LengthMismatch { taxel, counts: counts.len(), forces: force_n.len() });
    }
    let terms = kind.terms();
    let needed = 3 * terms;
    if counts.len() < needed {
        return Err(TactileForceError::TooFewSamples { taxel, samples: counts.len(), terms, needed });
    }
    if !counts.iter().flatten().all(|v| v.is_finite()) {
        return Err(TactileForceError::NotFinite { taxel, what: "a count" });
    }
    if !force_n.iter().flatten().all(|v| v.is_finite()) {
        return Err(TactileForceError::NotFinite { taxel, what: "a reference force" });
    }
    if force_n.iter().flatten().all(|v| *v == 0.0) {
        return Err(TactileForceError::NoForce { taxel });
    }
    let mut keep = vec![true; counts.len()];
    let mut map = solve(kind, taxel, counts, force_n, &keep)?;
    let residual = |map: &TaxelForceMap, k: usize| {
        let f = map.force_n(counts[k]);
        [0, 1, 2].map(|i| f[i] - force_n[k][i])
    };
    let norms: Vec<f64> =
        (0..counts.len()).map(|k| residual(&map, k).iter().map(|e| e * e).sum::<f64>().sqrt()).collect();
    let rms = (norms.iter().map(|r| r * r).sum::<f64>() / norms.len() as f64).sqrt();
    for (kept, r) in keep.iter_mut().zip(&norms) {
        *kept = *r <= OUTLIER_FACTOR * rms;
    }
    let outliers = keep.iter().filter(|k| !**k).count();
    if outliers > 0 {
        map = solve(kind, taxel, counts, force_n, &keep)?;
    }
    let kept = counts.len() - outliers;
    let mut sum_sq = [0.0; 3];
    for k in (0..counts.len()).filter(|k| keep[*k]) {
        let e = residual(&map, k);
        for (s, e) in sum_sq.iter_mut().zip(e) {
            *s += e * e;
        }
    }
    Ok(TaxelFit { map, outliers, rms_n: sum_sq.map(|s| (s / kept as f64).sqrt()) })
}

/// The least-squares map on the scans `keep` marks, with every term's
/// column scaled to unit RMS for the solve.
fn solve(
    kind: ForceModelKind,
    taxel: usize,
    counts: &[[f64; 3]],
    force_n: &[[f64; 3]],
    keep: &[bool],
) -> Result<TaxelForceMap, TactileForceError> {
    let rows: Vec<usize> = (0..counts.len()).filter(|k| keep[*k]).collect();
    let terms = kind.terms();
    if rows.len() < 3 * terms {
        let needed = 3 * terms;
        return Err(TactileForceError::TooFewSamples { taxel, samples: rows.len(), terms, needed });
    }
    let mut x = DMatrix::<f64>::zeros(rows.len(), terms);
    let mut y = DMatrix::<f64>::zeros(rows.len(), 3);
    let mut phi = Vec::with_capacity(terms);
    for (r, &k) in rows.iter().enumerate() {
        kind.features(counts[k], &mut phi);
        for (j, v) in phi.iter().enumerate() {
            x[(r, j)] = *v;
        }
        for (i, f) in force_n[k].iter().enumerate() {
            y[(r, i)] = *f;
        }
    }
    let scale: Vec<f64> = (0..terms)
        .map(|j| {
            let rms = (x.column(j).norm_squared() / rows.len() as f64).sqrt();
            if rms > 0.0 { rms } else { 1.0 }
        })
        .collect();
    for (j, s) in scale.iter().enumerate() {
        x.column_mut(j).unscale_mut(*s);
    }
    let svd = x.svd(true, true);
    let largest = svd.singular_values.max();
    let tolerance = RANK_TOLERANCE * largest;
    let rank = svd.singular_values.iter().filter(|s| **s > tolerance).count();
    if rank < terms {
        return Err(TactileForceError::Degenerate { taxel, rank, terms });
    }
    let beta = svd.solve(&y, tolerance).map_err(|_| TactileForceError::Degenerate { taxel, rank, terms })?;
    let coefficients: Vec<Vec<f64>> =
        (0..3).map(|i| (0..terms).map(|j| beta[(j, i)] / scale[j]).collect()).collect();
    let map = TaxelForceMap::from_rows(kind, [&coefficients[0], &coefficients[1], &coefficients[2]]);
    if !map.is_finite() {
        return Err(TactileForceError::NotFinite { taxel, what: "a fitted coefficient" });
    }
    Ok(map)
}
