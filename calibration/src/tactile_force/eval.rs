//! How well forces are predicted, and the trivial maps to compare with.

use serde::Serialize;

/// Errors of predicted forces against their references, per axis.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct AxisErrors {
    /// Root-mean-square error per axis `[x, y, z]` (N).
    pub rms_n: [f64; 3],
    /// Largest absolute error per axis (N).
    pub max_abs_n: [f64; 3],
    /// Range of the reference per axis, largest minus smallest (N).
    pub range_n: [f64; 3],
    /// Forces compared (taxels times scans).
    pub samples: usize,
}

impl AxisErrors {
    /// The RMS error of each axis as a fraction of its reference's range
    /// (infinite where the range is zero).
    pub fn rms_of_range(&self) -> [f64; 3] {
        [0, 1, 2].map(|i| if self.range_n[i] > 0.0 { self.rms_n[i] / self.range_n[i] } else { f64::INFINITY })
    }
}

/// The errors of `(predicted, reference)` pairs of forces (N).
pub fn axis_errors(pairs: impl IntoIterator<Item = ([f64; 3], [f64; 3])>) -> AxisErrors {
    let mut sum_sq = [0.0; 3];
    let mut max_abs = [0.0f64; 3];
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    let mut samples = 0;
    for (predicted, reference) in pairs {
        samples += 1;
        for (i, (p, r)) in predicted.iter().zip(&reference).enumerate() {
            let e = p - r;
            sum_sq[i] += e * e;
            max_abs[i] = max_abs[i].max(e.abs());
            lo[i] = lo[i].min(*r);
            hi[i] = hi[i].max(*r);
        }
    }
    if samples == 0 {
        return AxisErrors::default();
    }
    AxisErrors {
        rms_n: sum_sq.map(|s| (s / samples as f64).sqrt()),
        max_abs_n: max_abs,
        range_n: [0, 1, 2].map(|i| hi[i] - lo[i]),
        samples,
    }
}

/// The trivial map `F = k c`: one scale `k` (N/count) for every axis and
/// taxel, least squares through zero; 0 without counts.
pub fn fit_global_scale(counts: &[[f64; 3]], force_n: &[[f64; 3]]) -> f64 {
    let (mut cf, mut cc) = (0.0, 0.0);
    for (c, f) in counts.iter().zip(force_n) {
        for (c, f) in c.iter().zip(f) {
            cf += c * f;
            cc += c * c;
        }
    }
    if cc > 0.0 { cf / cc } else { 0.0 }
}

/// XELA's form of the map: per axis one slope and one intercept shared by
/// every taxel, no cross-talk (XELA fits it by orthogonal distance
/// regression on a sensor's summed counts; here by least squares per taxel).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct AxisSlopes {
    /// Force per count of the same axis `[x, y, z]` (N/count).
    pub slope_n_per_count: [f64; 3],
    /// Force at zero counts (N).
    pub intercept_n: [f64; 3],
}

impl AxisSlopes {
    /// The force (N) at tared `counts`.
    pub fn force_n(&self, counts: [f64; 3]) -> [f64; 3] {
        [0, 1, 2].map(|i| self.slope_n_per_count[i] * counts[i] + self.intercept_n[i])
    }
}

/// Fits [`AxisSlopes`] to tared `counts` and reference `force_n` of any taxels.
pub fn fit_axis_slopes(counts: &[[f64; 3]], force_n: &[[f64; 3]]) -> AxisSlopes {
    let n = counts.len().min(force_n.len()) as f64;
    let mut out = AxisSlopes::default();
    if n == 0.0 {
        return out;
    }
    for (i, (slope_out, intercept_out)) in
        out.slope_n_per_count.iter_mut().zip(out.intercept_n.iter_mut()).enumerate()
    {
        let mean_c = counts.iter().map(|c| c[i]).sum::<f64>() / n;
        let mean_f = force_n.iter().map(|f| f[i]).sum::<f64>() / n;
        let (mut cov, mut var) = (0.0, 0.0);
        for (c, f) in counts.iter().zip(force_n) {
            cov += (c[i] - mean_c) * (f[i] - mean_f);
            var += (c[i] - mean_c) * (c[i] - mean_c);
        }
        let slope = if var > 0.0 { cov / var } else { 0.0 };
        *slope_out = slope;
        *intercept_out = mean_f - slope * mean_c;
    }
    out
}
