//! Fitting: standardisation, the eigendecomposition that serves every
//! penalty, grouped cross-validation and the choice of each output's penalty.

use nalgebra::{DMatrix, DVector, SymmetricEigen};
use serde::Serialize;

use super::error::LinearMapError;
use super::map::LinearMap;

/// Options of [`LinearMap::fit`].
#[derive(Clone, Debug, PartialEq)]
pub struct FitOptions {
    /// Candidate penalties, each finite and positive (order and repeats do
    /// not matter). Default: 33 values log-spaced from 1e-3 to 1e5, four per
    /// decade.
    pub lambdas: Vec<f64>,
    /// Number of cross-validation folds, at least 2. Default 5.
    pub folds: usize,
}

impl Default for FitOptions {
    fn default() -> Self {
        FitOptions { lambdas: (-12..=20).map(|k| 10f64.powf(f64::from(k) / 4.0)).collect(), folds: 5 }
    }
}

/// How the rows were split for cross-validation.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case", tag = "kind")]
pub enum CvScheme {
    /// At least as many groups as [`FitOptions::folds`]: the group ids,
    /// sorted, are dealt round-robin into `folds` folds; all rows of a group
    /// are held out together.
    GroupedKFold {
        /// Folds used.
        folds: usize,
    },
    /// Two or more groups but fewer than [`FitOptions::folds`]: each group
    /// is held out in turn.
    LeaveOneGroupOut {
        /// Folds used (the number of groups).
        folds: usize,
    },
    /// A single group: the rows, in the order given, are cut into `folds`
    /// contiguous blocks (at most one per row). Neighbouring rows of a
    /// session are alike, so interleaved folds would leak; blocks leak only
    /// at their edges.
    RowBlocks {
        /// Folds used.
        folds: usize,
    },
    /// A single usable row: nothing to validate on. The largest candidate is
    /// taken; the weights are zero whatever the penalty.
    None,
}

/// What [`LinearMap::fit`] did.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FitReport {
    /// Rows fitted on.
    pub rows_used: usize,
    /// Rows skipped because an input or output was NaN or infinite.
    pub rows_skipped: usize,
    /// Distinct groups among the rows used.
    pub groups: usize,
    /// How the rows were split for cross-validation.
    pub scheme: CvScheme,
    /// The candidate penalties, ascending, without repeats.
    pub lambdas: Vec<f64>,
    /// `[output][candidate]`: the cross-validated mean squared error of each
    /// output (in its units, squared) for each candidate; NaN without
    /// cross-validation.
    pub cv_mse: Vec<Vec<f64>>,
    /// The penalty chosen for each output: the candidate with the smallest
    /// `cv_mse` (ties to the smaller penalty).
    pub lambda: Vec<f64>,
    /// In-sample coefficient of determination `1 − SSE/SST` of each output;
    /// NaN for an output that is constant over the rows used.
    pub r2: Vec<f64>,
}

/// The standardised ridge problem of some rows, decomposed once:
/// `ZᵀZ = V D Vᵀ` and `B = Vᵀ Zᵀ Ỹ`, so that the weights for any penalty are
/// `W = (V (D + λ I)⁻¹ B)ᵀ`.
struct Ridge {
    input_mean: Vec<f64>,
    input_std: Vec<f64>,
    output_mean: Vec<f64>,
    /// `V`, `[inputs, inputs]`.
    v: DMatrix<f64>,
    /// `D`, clamped at zero (rounding can make a null direction negative).
    d: Vec<f64>,
    /// `B`, `[inputs, outputs]`.
    b: DMatrix<f64>,
}

/// Mean and population standard deviation of each column of the rows
/// `rows` of the row-major `values` (`width` columns); a spread below 1e-12
/// of the mean's size (a constant column, up to rounding) is replaced by 1.
fn column_stats(
    values: &[f64],
    width: usize,
    rows: &[usize],
    what: &'static str,
) -> Result<(Vec<f64>, Vec<f64>), LinearMapError> {
    let n = rows.len() as f64;
    let mut mean = vec![0.0; width];
    for &r in rows {
        for (m, x) in mean.iter_mut().zip(&values[r * width..(r + 1) * width]) {
            *m += x;
        }
    }
    mean.iter_mut().for_each(|m| *m /= n);
    let mut var = vec![0.0; width];
    for &r in rows {
        for ((v, m), x) in var.iter_mut().zip(&mean).zip(&values[r * width..(r + 1) * width]) {
            *v += (x - m) * (x - m);
        }
    }
    let mut std = Vec::with_capacity(width);
    for (index, (v, m)) in var.iter().zip(&mean).enumerate() {
        let s = (v / n).sqrt();
        if !(s.is_finite() && m.is_finite()) {
            return Err(LinearMapError::Overflow { what, index });
        }
        std.push(if s <= 1e-12 * m.abs() || s == 0.0 { 1.0 } else { s });
    }
    Ok((mean, std))
}

impl Ridge {
    /// Standardises the rows `rows` and decomposes their problem.
    fn new(x: &[f64], y: &[f64], p: usize, q: usize, rows: &[usize]) -> Result<Self, LinearMapError> {
        let (input_mean, input_std) = column_stats(x, p, rows, "input")?;
        let (output_mean, _) = column_stats(y, q, rows, "output")?;
        let zt = standardised(x, p, rows, &input_mean, &input_std);
        let yt = DMatrix::from_fn(q, rows.len(), |o, r| y[rows[r] * q + o] - output_mean[o]);
        let gram = &zt * zt.transpose();
        let zty = &zt * yt.transpose();
        let eig = SymmetricEigen::try_new(gram, f64::EPSILON, 100 * (p + 10))
            .ok_or(LinearMapError::Decomposition { size: p })?;
        let d = eig.eigenvalues.iter().map(|v| v.max(0.0)).collect();
        let b = eig.eigenvectors.tr_mul(&zty);
        Ok(Ridge { input_mean, input_std, output_mean, v: eig.eigenvectors, d, b })
    }

    /// `W`, `[outputs, inputs]`, with the penalty `lambda[o]` for output `o`.
    fn weights(&self, lambda: &[f64]) -> DMatrix<f64> {
        let (p, q) = self.b.shape();
        let mut w = DMatrix::zeros(q, p);
        for (o, l) in lambda.iter().enumerate() {
            let s = DVector::from_fn(p, |k, _| self.b[(k, o)] / (self.d[k] + l));
            let w_o = &self.v * s;
            w.row_mut(o).copy_from(&w_o.transpose());
        }
        w
    }

    /// Adds to `sse[o][l]` the squared errors of output `o` on the rows
    /// `rows` predicted with the penalty `lambdas[l]`.
    fn add_held_out_sse(&self, x: &[f64], y: &[f64], rows: &[usize], lambdas: &[f64], sse: &mut [Vec<f64>]) {
        let (p, q) = self.b.shape();
        let zt = standardised(x, p, rows, &self.input_mean, &self.input_std);
        let projected = self.v.transpose() * zt;
        for (l, lambda) in lambdas.iter().enumerate() {
            let scaled_t = DMatrix::from_fn(q, p, |o, k| self.b[(k, o)] / (self.d[k] + lambda));
            let predicted = &scaled_t * &projected;
            for (j, &r) in rows.iter().enumerate() {
                for (o, sse_o) in sse.iter_mut().enumerate() {
                    let e = y[r * q + o] - self.output_mean[o] - predicted[(o, j)];
                    sse_o[l] += e * e;
                }
            }
        }
    }
}

/// `Zᵀ`, `[inputs, rows]`: one standardised row per column.
fn standardised(x: &[f64], p: usize, rows: &[usize], mean: &[f64], std: &[f64]) -> DMatrix<f64> {
    DMatrix::from_fn(p, rows.len(), |i, r| (x[rows[r] * p + i] - mean[i]) / std[i])
}

/// The fold of each used row, and the scheme (see [`CvScheme`]).
pub(super) fn assign_folds(used: &[usize], groups: &[usize], folds: usize) -> (CvScheme, Vec<usize>, usize) {
    let mut ids: Vec<usize> = used.iter().map(|&r| groups[r]).collect();
    ids.sort_unstable();
    ids.dedup();
    let n = used.len();
    if ids.len() >= 2 {
        let k = folds.min(ids.len());
        let scheme = if ids.len() >= folds {
            CvScheme::GroupedKFold { folds: k }
        } else {
            CvScheme::LeaveOneGroupOut { folds: k }
        };
        let fold = used.iter().map(|&r| ids.binary_search(&groups[r]).map_or(0, |rank| rank % k)).collect();
        (scheme, fold, ids.len())
    } else if n >= 2 {
        let k = folds.min(n);
        (CvScheme::RowBlocks { folds: k }, (0..n).map(|j| j * k / n).collect(), ids.len())
    } else {
        (CvScheme::None, vec![0; n], ids.len())
    }
}

/// Checked, unique channel names.
pub(super) fn names(what: &'static str, names: &[impl AsRef<str>]) -> Result<Vec<String>, LinearMapError> {
    if names.is_empty() {
        return Err(LinearMapError::NoChannels { what });
    }
    let owned: Vec<String> = names.iter().map(|n| n.as_ref().to_string()).collect();
    let mut sorted: Vec<&String> = owned.iter().collect();
    sorted.sort();
    if let Some(w) = sorted.windows(2).find(|w| w[0] == w[1]) {
        return Err(LinearMapError::DuplicateName { what, name: w[0].clone() });
    }
    Ok(owned)
}

/// The candidate penalties, ascending, without repeats.
fn candidates(opts: &FitOptions) -> Result<Vec<f64>, LinearMapError> {
    let bad = |detail: String| Err(LinearMapError::BadOptions { detail });
    if opts.folds < 2 {
        return bad(format!("{} folds, at least 2 needed", opts.folds));
    }
    if opts.lambdas.is_empty() {
        return bad("no candidate penalties".into());
    }
    if let Some(l) = opts.lambdas.iter().find(|l| !(l.is_finite() && **l > 0.0)) {
        return bad(format!("penalty {l} is not finite and positive"));
    }
    let mut lambdas = opts.lambdas.clone();
    lambdas.sort_by(f64::total_cmp);
    lambdas.dedup();
    Ok(lambdas)
}

impl LinearMap {
    /// Fits the map on rows of `inputs` (row-major, `input_names.len()` per
    /// row) and `outputs` (row-major, `output_names.len()` per row), one row
    /// per entry of `groups` (the session each row comes from). Rows with a
    /// NaN or infinite value are skipped (counted in the report). Each
    /// output's penalty is chosen by grouped cross-validation (module docs,
    /// [`CvScheme`]), then the map is fitted on all rows used. The report is
    /// also stored in the map's `meta` under `"fit"`.
    ///
    /// # Errors
    /// No rows, no channels, a repeated name, slices of the wrong length,
    /// every row non-finite, bad options, values whose statistics overflow.
    pub fn fit(
        inputs: &[f64],
        outputs: &[f64],
        groups: &[usize],
        input_names: &[impl AsRef<str>],
        output_names: &[impl AsRef<str>],
        opts: &FitOptions,
    ) -> Result<(LinearMap, FitReport), LinearMapError> {
        let input_names = names("input", input_names)?;
        let output_names = names("output", output_names)?;
        let (p, q, rows) = (input_names.len(), output_names.len(), groups.len());
        if rows == 0 {
            return Err(LinearMapError::NoRows);
        }
        for (what, width, got) in [("inputs", p, inputs.len()), ("outputs", q, outputs.len())] {
            if rows.saturating_mul(width) != got {
                return Err(LinearMapError::WidthMismatch {
                    what,
                    expected: rows.saturating_mul(width),
                    got,
                });
            }
        }
        let lambdas = candidates(opts)?;
        let finite = |v: &[f64]| v.iter().all(|x| x.is_finite());
        let used: Vec<usize> = (0..rows)
            .filter(|&r| finite(&inputs[r * p..(r + 1) * p]) && finite(&outputs[r * q..(r + 1) * q]))
            .collect();
        if used.is_empty() {
            return Err(LinearMapError::AllRowsNonFinite { rows });
        }
        let (scheme, fold_of, n_groups) = assign_folds(&used, groups, opts.folds);
        let cv_mse = cross_validate(inputs, outputs, (p, q), &used, &fold_of, &lambdas)?;
        let lambda: Vec<f64> = cv_mse.iter().map(|mse| choose(mse, &lambdas)).collect();
        let ridge = Ridge::new(inputs, outputs, p, q, &used)?;
        let weights = ridge.weights(&lambda);
        let mut map = LinearMap {
            input_names,
            output_names,
            input_mean: ridge.input_mean,
            input_std: ridge.input_std,
            output_mean: ridge.output_mean,
            weights,
            lambda: lambda.clone(),
            meta: serde_json::Value::Null,
        };
        let r2 = map.r_squared(inputs, outputs, &used);
        let report = FitReport {
            rows_used: used.len(),
            rows_skipped: rows - used.len(),
            groups: n_groups,
            scheme,
            lambdas,
            cv_mse,
            lambda,
            r2,
        };
        map.meta = serde_json::json!({ "fit": report });
        Ok((map, report))
    }

    /// In-sample `R²` of each output over the rows `used`.
    fn r_squared(&self, x: &[f64], y: &[f64], used: &[usize]) -> Vec<f64> {
        let (p, q) = (self.inputs(), self.outputs());
        let (mut sse, mut sst, mut predicted) = (vec![0.0; q], vec![0.0; q], vec![0.0; q]);
        for &r in used {
            self.apply(&x[r * p..(r + 1) * p], &mut predicted);
            for o in 0..q {
                let actual = y[r * q + o];
                sse[o] += (actual - predicted[o]).powi(2);
                sst[o] += (actual - self.output_mean[o]).powi(2);
            }
        }
        sse.iter().zip(&sst).map(|(e, t)| if *t > 0.0 { 1.0 - e / t } else { f64::NAN }).collect()
    }
}

/// `[output][candidate]` cross-validated mean squared errors (NaN with a
/// single fold, i.e. nothing to hold out).
fn cross_validate(
    x: &[f64],
    y: &[f64],
    (p, q): (usize, usize),
    used: &[usize],
    fold_of: &[usize],
    lambdas: &[f64],
) -> Result<Vec<Vec<f64>>, LinearMapError> {
    let folds = fold_of.iter().max().map_or(0, |f| f + 1);
    if folds < 2 {
        return Ok(vec![vec![f64::NAN; lambdas.len()]; q]);
    }
    let mut sse = vec![vec![0.0; lambdas.len()]; q];
    for f in 0..folds {
        let (mut held_out, mut train) = (Vec::new(), Vec::new());
        for (&r, &fold) in used.iter().zip(fold_of) {
            if fold == f { held_out.push(r) } else { train.push(r) }
        }
        Ridge::new(x, y, p, q, &train)?.add_held_out_sse(x, y, &held_out, lambdas, &mut sse);
    }
    let n = used.len() as f64;
    Ok(sse.into_iter().map(|s| s.into_iter().map(|e| e / n).collect()).collect())
}

/// The candidate with the smallest finite error (ties to the smaller), or the
/// largest candidate when no error is finite.
fn choose(mse: &[f64], lambdas: &[f64]) -> f64 {
    let mut best: Option<(f64, f64)> = None;
    for (e, l) in mse.iter().zip(lambdas) {
        if e.is_finite() && best.is_none_or(|(b, _)| *e < b) {
            best = Some((*e, *l));
        }
    }
    best.map_or(lambdas[lambdas.len() - 1], |(_, l)| l)
}
