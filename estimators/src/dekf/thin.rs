//! The training path's matrix products when a part of a batch is thin (at
//! most `mlp::THIN_COLUMNS` columns: parts of 1 or 2 windows),
//! register-blocked and compiled twice: for AVX2 with fused multiply-adds
//! where the CPU has them (chosen at run time through `pulp`'s safe
//! dispatch) and for the build's baseline elsewhere.
//!
//! nalgebra hands a product with a dimension of 5 or less to a plain loop
//! without FMA, and `matrixmultiply` packs both operands on every call,
//! which a product of 64 x 64 weights with 3 columns cannot repay; these
//! kernels read each weight once per group of [`COLS`] columns and keep the
//! sums in registers. `W^T dy` takes dot products along the weight's
//! columns (a copy of `W^T` per call cost 2.7 us for 64 x 64, more than
//! the product).
//!
//! Matrices are column-major slices: a weight `W` of `out x inp` is
//! `inp` columns of `out`, an activation `x` of `inp x n` is `n` columns of
//! `inp`. Every output is a sum in a fixed order that depends only on the
//! shapes and the instruction set, never on threads.

/// Columns computed together: a sample's value and its two tangents.
const COLS: usize = 3;

/// How a multiply-add is computed: fused (one rounding) inside the AVX2+FMA
/// dispatch, a product and a sum otherwise (a fused one without hardware
/// support would be a slow library call).
trait MulAdd: Copy {
    /// `a * b + c`.
    fn mul_add(a: f32, b: f32, c: f32) -> f32;
}

/// Fused: only used inside `pulp::x86::V3::vectorize`.
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy)]
struct Fused;

#[cfg(target_arch = "x86_64")]
impl MulAdd for Fused {
    #[inline(always)]
    fn mul_add(a: f32, b: f32, c: f32) -> f32 {
        a.mul_add(b, c)
    }
}

/// A product, then a sum.
#[derive(Clone, Copy)]
struct Separate;

impl MulAdd for Separate {
    #[inline(always)]
    fn mul_add(a: f32, b: f32, c: f32) -> f32 {
        a * b + c
    }
}

/// Rows per block with AVX2: 32 floats (4 registers) for each of 3 columns.
#[cfg(target_arch = "x86_64")]
const V3_ROWS: usize = 32;
/// Rows per block with the baseline (SSE2): 16 floats for each of 3 columns.
const PORTABLE_ROWS: usize = 16;

/// Shapes of a product: rows of the weight (`out`), its columns (`inp`),
/// and the columns of the activation (`n`).
#[derive(Clone, Copy, Debug)]
pub(super) struct Dims {
    pub out: usize,
    pub inp: usize,
    pub n: usize,
}

/// Runs `body` with fused multiply-adds and AVX2 where the CPU has them.
/// The closure is moved into `vectorize` and its captures moved inside it
/// (an `FnOnce` body inlines into the AVX2 function; see `infer.rs`).
macro_rules! dispatch {
    ($kernel:ident, $v3_rows:expr, $portable_rows:expr, $($arg:ident),*) => {{
        #[cfg(target_arch = "x86_64")]
        if let Some(simd) = pulp::x86::V3::try_new() {
            return simd.vectorize(
                #[inline(always)]
                move || {
                    $(let $arg = $arg;)*
                    $kernel::<Fused, { $v3_rows }>($($arg),*)
                },
            );
        }
        $kernel::<Separate, { $portable_rows }>($($arg),*)
    }};
}

/// `y = W x` (`y` is `out x n`, overwritten).
pub(super) fn mul(w: &[f32], d: Dims, x: &[f32], y: &mut [f32]) {
    check(w, d, x, y);
    dispatch!(mul_with, V3_ROWS, PORTABLE_ROWS, w, d, x, y)
}

/// `dx = W^T dy` (`dy` is `out x n`, `dx` is `inp x n`, overwritten).
pub(super) fn mul_transposed(w: &[f32], d: Dims, dy: &[f32], dx: &mut [f32]) {
    check(w, d, dx, dy);
    dispatch!(mul_transposed_with, V3_ROWS, PORTABLE_ROWS, w, d, dy, dx)
}

/// `gw += dy x^T` (`gw` is `out x inp`, `dy` is `out x n`, `x` is `inp x n`).
pub(super) fn add_outer(gw: &mut [f32], d: Dims, dy: &[f32], x: &[f32]) {
    check(gw, d, x, dy);
    dispatch!(add_outer_with, V3_ROWS / 2, PORTABLE_ROWS / 2, gw, d, dy, x)
}

fn check(w: &[f32], d: Dims, x: &[f32], y: &[f32]) {
    assert!(
        w.len() == d.out * d.inp && x.len() == d.inp * d.n && y.len() == d.out * d.n,
        "thin product shapes {d:?}: {} {} {}",
        w.len(),
        x.len(),
        y.len()
    );
}

/// Calls `f(first column, J)` over the columns `0..n` in groups of
/// [`COLS`], the last group 1 or 2 wide.
macro_rules! by_column_groups {
    ($n:expr, |$j:ident, $width:ident| $body:expr) => {{
        let mut $j = 0;
        while $j < $n {
            match $n - $j {
                1 => {
                    const $width: usize = 1;
                    $body;
                    $j += 1;
                }
                2 => {
                    const $width: usize = 2;
                    $body;
                    $j += 2;
                }
                _ => {
                    const $width: usize = COLS;
                    $body;
                    $j += COLS;
                }
            }
        }
    }};
}

#[inline(always)]
fn mul_with<M: MulAdd, const B: usize>(w: &[f32], d: Dims, x: &[f32], y: &mut [f32]) {
    let Dims { out, inp, n } = d;
    by_column_groups!(n, |j, J| mul_cols::<M, B, J>(
        w,
        out,
        &x[j * inp..(j + J) * inp],
        &mut y[j * out..(j + J) * out]
    ));
}

/// `J` columns of `y = W x`: blocks of `B` rows keep `J x B` sums in
/// registers while every weight column is added in input order.
#[inline(always)]
fn mul_cols<M: MulAdd, const B: usize, const J: usize>(w: &[f32], out: usize, x: &[f32], y: &mut [f32]) {
    let inp = x.len() / J;
    let mut o = 0;
    while o + B <= out {
        let mut acc = [[0.0f32; B]; J];
        for k in 0..inp {
            let c: &[f32; B] = w[k * out + o..k * out + o + B].try_into().expect("a whole block");
            for (j, a) in acc.iter_mut().enumerate() {
                let xk = x[j * inp + k];
                for (ar, cr) in a.iter_mut().zip(c) {
                    *ar = M::mul_add(*cr, xk, *ar);
                }
            }
        }
        for (j, a) in acc.iter().enumerate() {
            y[j * out + o..j * out + o + B].copy_from_slice(a);
        }
        o += B;
    }
    for r in o..out {
        for j in 0..J {
            let mut s = 0.0f32;
            for k in 0..inp {
                s = M::mul_add(w[k * out + r], x[j * inp + k], s);
            }
            y[j * out + r] = s;
        }
    }
}

/// `dx = W^T dy`: for every weight column `k` and each of `J` columns of
/// `dy`, the dot product `W[:, k] . dy[:, j]` in eight lanes, the lanes
/// added in a fixed tree, then the rows past the last eight in order.
#[inline(always)]
fn mul_transposed_with<M: MulAdd, const B: usize>(w: &[f32], d: Dims, dy: &[f32], dx: &mut [f32]) {
    let Dims { out, inp, n } = d;
    by_column_groups!(n, |j, J| dots::<M, J>(
        w,
        out,
        &dy[j * out..(j + J) * out],
        &mut dx[j * inp..(j + J) * inp]
    ));
}

#[inline(always)]
fn dots<M: MulAdd, const J: usize>(w: &[f32], out: usize, dy: &[f32], dx: &mut [f32]) {
    let inp = dx.len() / J;
    // (Two sums per column, even and odd groups of eight rows, measured
    // slower: the sums no longer stayed in registers.)
    let whole = out / 8 * 8;
    for (k, c) in w.chunks_exact(out).enumerate() {
        let mut acc = [[0.0f32; 8]; J];
        for o in (0..whole).step_by(8) {
            let ck: &[f32; 8] = c[o..o + 8].try_into().expect("eight");
            for (j, a) in acc.iter_mut().enumerate() {
                let dj: &[f32; 8] = dy[j * out + o..j * out + o + 8].try_into().expect("eight");
                for l in 0..8 {
                    a[l] = M::mul_add(ck[l], dj[l], a[l]);
                }
            }
        }
        for (j, a) in acc.iter().enumerate() {
            let mut s = ((a[0] + a[4]) + (a[2] + a[6])) + ((a[1] + a[5]) + (a[3] + a[7]));
            for r in whole..out {
                s = M::mul_add(c[r], dy[j * out + r], s);
            }
            dx[j * inp + k] = s;
        }
    }
}

#[inline(always)]
fn add_outer_with<M: MulAdd, const B: usize>(gw: &mut [f32], d: Dims, dy: &[f32], x: &[f32]) {
    let Dims { out, inp, n } = d;
    by_column_groups!(n, |j, J| outer_cols::<M, B, J>(
        gw,
        out,
        &dy[j * out..(j + J) * out],
        &x[j * inp..(j + J) * inp]
    ));
}

/// `gw += sum_j dy[:, j] x[:, j]^T` over `J` columns: blocks of `B` rows
/// (half those of the other products: `J x B` of `dy` and `B` sums fit the
/// registers) of `dy` stay in registers while every column of `gw` is read, updated in
/// column order of `j`, and stored once.
#[inline(always)]
fn outer_cols<M: MulAdd, const B: usize, const J: usize>(gw: &mut [f32], out: usize, dy: &[f32], x: &[f32]) {
    let inp = x.len() / J;
    let mut o = 0;
    while o + B <= out {
        let mut d = [[0.0f32; B]; J];
        for (j, dj) in d.iter_mut().enumerate() {
            dj.copy_from_slice(&dy[j * out + o..j * out + o + B]);
        }
        for k in 0..inp {
            let g: &mut [f32; B] = (&mut gw[k * out + o..k * out + o + B]).try_into().expect("a whole block");
            let mut acc = *g;
            for (j, dj) in d.iter().enumerate() {
                let xk = x[j * inp + k];
                for (ar, dr) in acc.iter_mut().zip(dj) {
                    *ar = M::mul_add(*dr, xk, *ar);
                }
            }
            *g = acc;
        }
        o += B;
    }
    for r in o..out {
        for k in 0..inp {
            let mut s = gw[k * out + r];
            for j in 0..J {
                s = M::mul_add(dy[j * out + r], x[j * inp + k], s);
            }
            gw[k * out + r] = s;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn filled(len: usize, seed: usize) -> Vec<f32> {
        (0..len).map(|k| (((k * 37 + seed * 11) % 101) as f32 - 50.0) / 25.0).collect()
    }

    /// Every kernel against the plain triple loop in f64, for the thesis's
    /// 64 x 64 layers, the 1-row output layer, the 2-column input layer and
    /// widths that leave row and lane remainders, with 1 to 12 columns
    /// (groups of 3 and the 1- and 2-wide last group); the portable and the
    /// AVX2 build. Catches a wrong offset of a column group, a row block or
    /// a lane remainder, and a lost or doubled term.
    #[test]
    fn the_thin_products_equal_the_plain_ones() {
        for (out, inp) in [(64, 64), (1, 64), (64, 2), (20, 13), (13, 20), (9, 1), (70, 33)] {
            for n in [1, 2, 3, 4, 5, 6, 7, 12] {
                let d = Dims { out, inp, n };
                let w = filled(out * inp, 1);
                let x = filled(inp * n, 2);
                let dy = filled(out * n, 3);
                let g0 = filled(out * inp, 4);
                let close = |got: f32, want: f64, what: &str| {
                    assert!(
                        (f64::from(got) - want).abs() < 1e-4 * (1.0 + want.abs()),
                        "{what} {d:?}: {got} vs {want}"
                    );
                };
                let mut y = vec![f32::NAN; out * n];
                let mut dx = vec![f32::NAN; inp * n];
                let mut gw = g0.clone();
                let mut runs: Vec<(&str, [Vec<f32>; 3])> = Vec::new();
                mul_with::<Separate, PORTABLE_ROWS>(&w, d, &x, &mut y);
                mul_transposed_with::<Separate, PORTABLE_ROWS>(&w, d, &dy, &mut dx);
                add_outer_with::<Separate, { PORTABLE_ROWS / 2 }>(&mut gw, d, &dy, &x);
                runs.push(("portable", [y.clone(), dx.clone(), gw.clone()]));
                let mut gw = g0.clone();
                mul(&w, d, &x, &mut y);
                mul_transposed(&w, d, &dy, &mut dx);
                add_outer(&mut gw, d, &dy, &x);
                runs.push(("dispatched", [y, dx, gw]));
                for (what, [y, dx, gw]) in &runs {
                    for j in 0..n {
                        for r in 0..out {
                            let want: f64 =
                                (0..inp).map(|k| f64::from(w[k * out + r]) * f64::from(x[j * inp + k])).sum();
                            close(y[j * out + r], want, what);
                        }
                        for k in 0..inp {
                            let want: f64 = (0..out)
                                .map(|r| f64::from(w[k * out + r]) * f64::from(dy[j * out + r]))
                                .sum();
                            close(dx[j * inp + k], want, what);
                        }
                    }
                    for k in 0..inp {
                        for r in 0..out {
                            let want = f64::from(g0[k * out + r])
                                + (0..n)
                                    .map(|j| f64::from(dy[j * out + r]) * f64::from(x[j * inp + k]))
                                    .sum::<f64>();
                            close(gw[k * out + r], want, what);
                        }
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod timing {
    use super::*;
    use nalgebra::DMatrix;
    use std::time::Instant;

    /// The least time of `reps` calls of `f`, in nanoseconds per call.
    fn least_ns(reps: usize, mut f: impl FnMut()) -> f64 {
        let mut best = f64::INFINITY;
        for _ in 0..20 {
            let t = Instant::now();
            for _ in 0..reps {
                f();
            }
            best = best.min(t.elapsed().as_secs_f64() * 1e9 / reps as f64);
        }
        best
    }

    /// The three products of a 64 x 64 layer with these kernels and with
    /// nalgebra, per column (`cargo test --release -p
    /// slidetrack-estimators --lib time_the_thin_products -- --ignored
    /// --nocapture`).
    #[test]
    #[ignore = "a timing, not a check"]
    fn time_the_thin_products() {
        let (out, inp) = (64, 64);
        for n in [1, 3, 6, 12, 16, 48] {
            let d = Dims { out, inp, n };
            let w = DMatrix::<f32>::from_fn(out, inp, |r, c| ((r * 7 + c * 3) % 11) as f32 * 0.1 - 0.5);
            let x = DMatrix::<f32>::from_fn(inp, n, |r, c| ((r * 5 + c) % 13) as f32 * 0.1 - 0.6);
            let dy = DMatrix::<f32>::from_fn(out, n, |r, c| ((r * 3 + c) % 7) as f32 * 0.1 - 0.3);
            let mut y = DMatrix::<f32>::zeros(out, n);
            let mut dx = DMatrix::<f32>::zeros(inp, n);
            let mut gw = DMatrix::<f32>::zeros(out, inp);
            let reps = 20_000 / n;
            let thin = [
                least_ns(reps, || mul(w.as_slice(), d, x.as_slice(), y.as_mut_slice())),
                least_ns(reps, || mul_transposed(w.as_slice(), d, dy.as_slice(), dx.as_mut_slice())),
                least_ns(reps, || add_outer(gw.as_mut_slice(), d, dy.as_slice(), x.as_slice())),
            ];
            let xt = x.transpose();
            let nal = [
                least_ns(reps, || y.gemm(1.0, &w, &x, 0.0)),
                least_ns(reps, || {
                    // As `mlp` does: `W^T` as a strided view when every
                    // dimension exceeds 5, `gemm_tr` otherwise.
                    if n > 5 {
                        let wt = nalgebra::MatrixView::<
                            f32,
                            nalgebra::Dyn,
                            nalgebra::Dyn,
                            nalgebra::Dyn,
                            nalgebra::Dyn,
                        >::from_slice_with_strides(
                            w.as_slice(), inp, out, out, 1
                        );
                        dx.gemm(1.0, &wt, &dy, 0.0);
                    } else {
                        dx.gemm_tr(1.0, &w, &dy, 0.0);
                    }
                }),
                least_ns(reps, || gw.gemm(1.0, &dy, &xt, 1.0)),
            ];
            let per = |v: [f64; 3]| v.map(|t| format!("{:.0}", t / n as f64)).join(" ");
            println!("n {n:>2}: ns per column W x, W^T dy, dy x^T: thin {} nalgebra {}", per(thin), per(nal));
        }
    }
}
