//! Fitting checks: exact recovery, the closed form, the choice of the
//! penalty (grouped, per output), degenerate inputs and non-finite rows.
//! The file checks are in `file_tests.rs`.

use nalgebra::DMatrix;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

use super::fit::assign_folds;
use super::*;

pub(super) fn names(prefix: &str, n: usize) -> Vec<String> {
    (0..n).map(|i| format!("{prefix}{i}")).collect()
}

pub(super) fn gaussian(rng: &mut ChaCha8Rng, n: usize) -> Vec<f64> {
    (0..n).map(|_| StandardNormal.sample(rng)).collect()
}

/// Rows of `y = A x + noise·ε` with standard normal `x` (row-major).
fn linear_data(rng: &mut ChaCha8Rng, a: &DMatrix<f64>, rows: usize, noise: f64) -> (Vec<f64>, Vec<f64>) {
    let (q, p) = a.shape();
    let x = gaussian(rng, rows * p);
    let mut y = Vec::with_capacity(rows * q);
    for r in 0..rows {
        for o in 0..q {
            let s: f64 = (0..p).map(|i| a[(o, i)] * x[r * p + i]).sum();
            y.push(s + noise * Distribution::<f64>::sample(&StandardNormal, rng));
        }
    }
    (x, y)
}

/// Mean squared error of `map` on rows of `x`, `y`.
fn mse(map: &LinearMap, x: &[f64], y: &[f64]) -> f64 {
    let (p, q) = (map.inputs(), map.outputs());
    let mut out = vec![0.0; q];
    let mut sum = 0.0;
    for (xr, yr) in x.chunks(p).zip(y.chunks(q)) {
        map.apply(xr, &mut out);
        sum += out.iter().zip(yr).map(|(a, b)| (a - b).powi(2)).sum::<f64>();
    }
    sum / (y.len() as f64)
}

fn only(lambda: f64) -> FitOptions {
    FitOptions { lambdas: vec![lambda], ..FitOptions::default() }
}

/// Catches: weights not mapped back to input units (the inputs have offsets
/// up to 1e3 and spreads from 1e-3 to 10), a wrong bias, a penalised
/// intercept, `[inputs, outputs]` transposed.
#[test]
fn a_noise_free_linear_map_is_recovered_exactly() {
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let (p, q, n) = (5, 3, 60);
    let (offset, scale) = ([0.0, 100.0, -5.0, 1e3, 0.5], [1.0, 0.01, 10.0, 3.0, 1e-3]);
    let a = DMatrix::from_vec(q, p, gaussian(&mut rng, q * p));
    let b = gaussian(&mut rng, q);
    let x_of = |z: &[f64]| -> Vec<f64> { (0..p).map(|i| offset[i] + scale[i] * z[i]).collect() };
    let truth = |x: &[f64]| -> Vec<f64> {
        (0..q).map(|o| b[o] + (0..p).map(|i| a[(o, i)] * x[i]).sum::<f64>()).collect()
    };
    let x: Vec<f64> = gaussian(&mut rng, n * p).chunks(p).flat_map(x_of).collect();
    let y: Vec<f64> = x.chunks(p).flat_map(truth).collect();
    let groups: Vec<usize> = (0..n).map(|r| r % 6).collect();
    let opts = FitOptions { lambdas: vec![1e-12, 1e-10], ..FitOptions::default() };
    let (map, report) = LinearMap::fit(&x, &y, &groups, &names("x", p), &names("y", q), &opts).unwrap();
    assert_eq!(report.rows_used, n);
    let (w, bias) = map.affine();
    for o in 0..q {
        assert!((bias[o] - b[o]).abs() < 1e-8, "bias {o}: {} vs {}", bias[o], b[o]);
        for i in 0..p {
            assert!((w[(o, i)] - a[(o, i)]).abs() < 1e-8, "W[{o},{i}]: {} vs {}", w[(o, i)], a[(o, i)]);
        }
    }
    let mut out = vec![0.0; q];
    for z in gaussian(&mut rng, 20 * p).chunks(p) {
        let x = x_of(z);
        map.apply(&x, &mut out);
        for (got, want) in out.iter().zip(truth(&x)) {
            assert!((got - want).abs() < 1e-8 * (1.0 + want.abs()), "{got} vs {want}");
        }
    }
}

/// Catches: a penalty scaled by the number of rows, the sample instead of
/// the population standard deviation, a penalised intercept, an error in
/// the eigendecomposition route.
#[test]
fn the_weights_are_the_closed_form_ridge_solution() {
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    let (p, q, n, lambda) = (3, 2, 8, 2.5);
    let x: Vec<f64> =
        gaussian(&mut rng, n * p).iter().enumerate().map(|(k, v)| v * (1.0 + k as f64 % 3.0) + 4.0).collect();
    let y: Vec<f64> = gaussian(&mut rng, n * q).iter().map(|v| 3.0 * v - 1.0).collect();
    let groups: Vec<usize> = (0..n).map(|r| r / 2).collect();
    let (map, _) = LinearMap::fit(&x, &y, &groups, &names("x", p), &names("y", q), &only(lambda)).unwrap();

    let xm = DMatrix::from_row_slice(n, p, &x);
    let ym = DMatrix::from_row_slice(n, q, &y);
    let mean = xm.row_mean();
    let std = xm.row_variance().map(f64::sqrt); // population variance
    let z = DMatrix::from_fn(n, p, |r, i| (xm[(r, i)] - mean[i]) / std[i]);
    let yc = DMatrix::from_fn(n, q, |r, o| ym[(r, o)] - ym.column(o).mean());
    let lhs = z.transpose() * &z + DMatrix::identity(p, p) * lambda;
    let w = lhs.cholesky().unwrap().solve(&(z.transpose() * yc)).transpose();
    assert_eq!(map.weights.shape(), (q, p));
    for (got, want) in map.weights.iter().zip(w.iter()) {
        assert!((got - want).abs() < 1e-12 * (1.0 + want.abs()), "{got} vs {want}");
    }
    for i in 0..p {
        assert!((map.input_mean[i] - mean[i]).abs() < 1e-12 && (map.input_std[i] - std[i]).abs() < 1e-12);
    }
    assert_eq!(map.lambda, vec![lambda; q]);
}

/// Catches: choosing the penalty by the training error (always the
/// smallest), or cross-validation that does not hold rows out.
#[test]
fn noisy_data_with_irrelevant_inputs_gets_a_penalty_that_beats_least_squares() {
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let (p, n) = (40, 80);
    let mut a = DMatrix::zeros(1, p);
    a[(0, 0)] = 1.0;
    a[(0, 1)] = -0.5;
    a[(0, 2)] = 0.7;
    let (x, y) = linear_data(&mut rng, &a, n, 1.0);
    let groups: Vec<usize> = (0..n).map(|r| r / 5).collect();
    let fit = |opts: &FitOptions| LinearMap::fit(&x, &y, &groups, &names("x", p), &["y"], opts).unwrap();
    let (ridge, report) = fit(&FitOptions::default());
    let (least_squares, _) = fit(&only(1e-9));
    assert!(report.lambda[0] > report.lambdas[0], "chose the smallest penalty: {report:?}");
    let (x_test, y_test) = linear_data(&mut rng, &a, 2000, 1.0);
    let (e_ridge, e_ls) = (mse(&ridge, &x_test, &y_test), mse(&least_squares, &x_test, &y_test));
    assert!(e_ridge < 0.9 * e_ls, "ridge {e_ridge} vs least squares {e_ls} (λ = {})", report.lambda[0]);
}

/// Ten sessions, each one point repeated twenty times, outputs pure noise,
/// rows shuffled. Held out by session, an interpolating fit predicts nothing:
/// a large penalty wins. Held out by row, every held-out row has copies in
/// the training rows and the smallest penalty wins, as it does here when
/// each row is its own group. Catches: folds over rows (interleaved or in
/// blocks) that ignore the groups.
#[test]
fn cross_validation_holds_out_whole_groups() {
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    let (p, sessions, copies) = (20, 10, 20);
    let points = gaussian(&mut rng, sessions * p);
    let noise = gaussian(&mut rng, sessions);
    let mut order: Vec<usize> = (0..sessions * copies).map(|k| k % sessions).collect();
    for k in (1..order.len()).rev() {
        order.swap(k, rng.random_range(0..=k));
    }
    let x: Vec<f64> = order.iter().flat_map(|&g| points[g * p..(g + 1) * p].to_vec()).collect();
    let y: Vec<f64> = order.iter().map(|&g| noise[g]).collect();
    let fit =
        |groups: &[usize]| LinearMap::fit(&x, &y, groups, &names("x", p), &["y"], &FitOptions::default());
    let (_, by_session) = fit(&order).unwrap();
    assert_eq!(by_session.scheme, CvScheme::GroupedKFold { folds: 5 });
    assert!(by_session.lambda[0] >= 100.0, "grouped CV chose {}", by_session.lambda[0]);
    let rows: Vec<usize> = (0..order.len()).collect();
    let (_, by_row) = fit(&rows).unwrap();
    assert_eq!(by_row.lambda[0], by_row.lambdas[0], "row-wise CV should leak and pick the smallest");
}

/// A noise-free output in µm (numbers ~1e3) beside a pure-noise output:
/// each gets its own penalty, and rescaling an output changes no choice.
/// Catches: one penalty for all outputs, or selection on the summed errors
/// in the outputs' units.
#[test]
fn each_output_gets_its_own_penalty_whatever_its_units() {
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let (p, n) = (5, 100);
    let a = DMatrix::from_vec(1, p, gaussian(&mut rng, p)) * 1e3;
    let (x, clean) = linear_data(&mut rng, &a, n, 0.0);
    let noise = gaussian(&mut rng, n);
    let groups: Vec<usize> = (0..n).map(|r| r % 10).collect();
    let fit = |noise_scale: f64| {
        let y: Vec<f64> = clean.iter().zip(&noise).flat_map(|(c, e)| [*c, noise_scale * e]).collect();
        LinearMap::fit(&x, &y, &groups, &names("x", p), &["position_um", "noise"], &FitOptions::default())
            .unwrap()
    };
    let (map, report) = fit(1.0);
    assert_eq!(report.lambda[0], report.lambdas[0], "the noise-free output takes the smallest penalty");
    assert!(report.lambda[1] >= 100.0, "the noise output takes a large penalty: {:?}", report.lambda);
    assert_eq!(map.lambda, report.lambda);
    for scale in [1e-4, 1e4] {
        let (scaled, r) = fit(scale);
        assert_eq!(r.lambda, report.lambda, "scale {scale}");
        for i in 0..p {
            let (got, want) = (scaled.weights[(1, i)], scale * map.weights[(1, i)]);
            assert!((got - want).abs() <= 1e-9 * want.abs().max(1e-300), "{got} vs {want}");
        }
    }
}

/// Catches: division by a zero spread (NaN weights), a failed solve on a
/// singular `ZᵀZ`, or asymmetric treatment of identical columns.
#[test]
fn more_inputs_than_rows_constant_and_collinear_inputs_give_finite_weights() {
    let mut rng = ChaCha8Rng::seed_from_u64(6);
    let (n, p) = (10, 30);
    let base = gaussian(&mut rng, n * 10);
    let consts = [0.0, 3.7, 1e6, -2.5e-3, 42.0, 7.0, 1.0, -1.0, 1e-9];
    let x: Vec<f64> = (0..n)
        .flat_map(|r| {
            let row = &base[r * 10..(r + 1) * 10];
            row.iter().chain(row).copied().chain(consts).chain([2.0 * row[0] + 1.0]).collect::<Vec<_>>()
        })
        .collect();
    let y: Vec<f64> = (0..n).flat_map(|r| [base[r * 10] - base[r * 10 + 3], 5.0]).collect();
    let groups: Vec<usize> = (0..n).map(|r| r / 2).collect();
    let (map, report) =
        LinearMap::fit(&x, &y, &groups, &names("x", p), &["a", "constant"], &FitOptions::default()).unwrap();
    assert!(map.weights.iter().all(|w| w.is_finite()), "{}", map.weights);
    assert!(map.input_std.iter().all(|s| s.is_finite() && *s > 0.0));
    for o in 0..2 {
        for i in 0..10 {
            let (w, twin) = (map.weights[(o, i)], map.weights[(o, i + 10)]);
            assert!((w - twin).abs() <= 1e-9 * (1.0 + w.abs()), "columns {i} and {}: {w} vs {twin}", i + 10);
        }
        for i in 20..29 {
            assert!(map.weights[(o, i)].abs() < 1e-6, "constant column {i}: {}", map.weights[(o, i)]);
        }
    }
    let mut out = [0.0; 2];
    map.apply(&x[..p], &mut out);
    assert!(out.iter().all(|v| v.is_finite()) && (out[1] - 5.0).abs() < 1e-9, "{out:?}");
    assert!(report.r2[1].is_nan(), "a constant output has no R²");
}

/// Catches: NaN leaking into the fit, skipped rows not counted, `apply`
/// turning a NaN input into a finite output (a zero weight would).
#[test]
fn non_finite_rows_are_skipped_and_counted() {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let (p, n) = (4, 50);
    let a = DMatrix::from_vec(2, p, gaussian(&mut rng, 2 * p));
    let (mut x, mut y) = linear_data(&mut rng, &a, n, 0.1);
    let groups: Vec<usize> = (0..n).map(|r| r % 5).collect();
    let bad_rows = [3, 17, 18, 40, 49];
    let clean = |v: &[f64], w: usize| -> Vec<f64> {
        v.chunks(w).enumerate().filter(|(r, _)| !bad_rows.contains(r)).flat_map(|(_, c)| c.to_vec()).collect()
    };
    let (x_clean, y_clean) = (clean(&x, p), clean(&y, 2));
    let groups_clean: Vec<usize> =
        groups.iter().enumerate().filter(|(r, _)| !bad_rows.contains(r)).map(|(_, g)| *g).collect();
    x[3 * p + 1] = f64::NAN;
    x[17 * p] = f64::INFINITY;
    x[18 * p + 3] = f64::NEG_INFINITY;
    y[40 * 2 + 1] = f64::NAN;
    y[49 * 2] = f64::INFINITY;
    let fit = |x: &[f64], y: &[f64], g: &[usize]| {
        LinearMap::fit(x, y, g, &names("x", p), &["u", "v"], &FitOptions::default()).unwrap()
    };
    let (map, report) = fit(&x, &y, &groups);
    assert_eq!((report.rows_used, report.rows_skipped), (n - 5, 5));
    let (reference, _) = fit(&x_clean, &y_clean, &groups_clean);
    assert_eq!(map.weights, reference.weights);
    assert_eq!(map.output_mean, reference.output_mean);
    let mut out = [0.0; 2];
    for bad in [f64::NAN, f64::INFINITY] {
        let mut input = vec![0.5; p];
        input[2] = bad;
        map.apply(&input, &mut out);
        assert!(out.iter().all(|v| v.is_nan()), "{out:?}");
    }
    let all_nan = vec![f64::NAN; n * p];
    let e = LinearMap::fit(&all_nan, &y, &groups, &names("x", p), &["u", "v"], &FitOptions::default())
        .unwrap_err();
    assert!(matches!(e, LinearMapError::AllRowsNonFinite { rows: 50 }), "{e}");
}

/// Catches: unchecked widths and options turning into panics or nonsense.
#[test]
fn bad_calls_are_refused_with_the_facts() {
    let fit = |x: &[f64], y: &[f64], g: &[usize], inputs: &[&str], opts: &FitOptions| {
        LinearMap::fit(x, y, g, inputs, &["y"], opts).unwrap_err()
    };
    let d = FitOptions::default();
    assert!(matches!(fit(&[], &[], &[], &["a"], &d), LinearMapError::NoRows));
    let e = fit(&[1.0, 2.0, 3.0], &[1.0, 2.0], &[0, 1], &["a", "b"], &d);
    assert!(matches!(e, LinearMapError::WidthMismatch { what: "inputs", expected: 4, got: 3 }), "{e}");
    let e = fit(&[1.0, 2.0], &[1.0], &[0, 1], &["a"], &d);
    assert!(matches!(e, LinearMapError::WidthMismatch { what: "outputs", expected: 2, got: 1 }), "{e}");
    assert!(matches!(fit(&[1.0], &[1.0], &[0], &[], &d), LinearMapError::NoChannels { what: "input" }));
    let e = fit(&[1.0, 2.0], &[1.0], &[0], &["a", "a"], &d);
    assert!(matches!(&e, LinearMapError::DuplicateName { what: "input", name } if name == "a"), "{e}");
    for opts in [
        FitOptions { folds: 1, ..d.clone() },
        only(0.0),
        only(f64::NAN),
        FitOptions { lambdas: vec![], folds: 5 },
    ] {
        assert!(
            matches!(fit(&[1.0], &[1.0], &[0], &["a"], &opts), LinearMapError::BadOptions { .. }),
            "{opts:?}"
        );
    }
}

/// Catches: folds that depend on the rows' order or a hash, and the
/// fallbacks for few groups.
#[test]
fn folds_deal_sorted_groups_round_robin_with_fallbacks() {
    let groups = [7, 3, 3, 9, 1, 7];
    let used: Vec<usize> = (0..6).collect();
    let (scheme, folds, n) = assign_folds(&used, &groups, 2);
    assert_eq!((scheme, n), (CvScheme::GroupedKFold { folds: 2 }, 4));
    assert_eq!(folds, [0, 1, 1, 1, 0, 0]); // 1 → 0, 3 → 1, 7 → 0, 9 → 1
    assert_eq!(assign_folds(&used, &groups, 5).0, CvScheme::LeaveOneGroupOut { folds: 4 });
    let (scheme, folds, _) = assign_folds(&used, &[4; 6], 4);
    assert_eq!((scheme, folds), (CvScheme::RowBlocks { folds: 4 }, vec![0, 0, 1, 2, 2, 3]));
    assert_eq!(assign_folds(&[2], &[0, 0, 5], 5).0, CvScheme::None);
    // A single row still fits: the mean, zero weights.
    let (map, report) =
        LinearMap::fit(&[1.0, 2.0], &[3.0], &[0], &["a", "b"], &["y"], &FitOptions::default()).unwrap();
    assert_eq!(report.scheme, CvScheme::None);
    let mut out = [0.0];
    map.apply(&[5.0, -5.0], &mut out);
    assert_eq!(out, [3.0]);
}

/// Measures the fit time of a realistic size; run with
/// `cargo test --release -p slidetrack-estimators linear_map::tests::fit_time -- --ignored --nocapture`.
#[test]
#[ignore = "a timing, not a check"]
fn fit_time_10000_rows_200_inputs_6_outputs() {
    let mut rng = ChaCha8Rng::seed_from_u64(8);
    let (p, q, n) = (200, 6, 10_000);
    let a = DMatrix::from_vec(q, p, gaussian(&mut rng, q * p));
    let (x, y) = linear_data(&mut rng, &a, n, 1.0);
    let groups: Vec<usize> = (0..n).map(|r| r / 500).collect();
    let start = std::time::Instant::now();
    let (_, report) =
        LinearMap::fit(&x, &y, &groups, &names("x", p), &names("y", q), &FitOptions::default()).unwrap();
    println!(
        "fit {n} x {p} x {q}, {} candidates, {:?}: {:?}",
        report.lambdas.len(),
        report.scheme,
        start.elapsed()
    );
}
