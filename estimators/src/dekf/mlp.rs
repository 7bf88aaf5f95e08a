//! The residual MLP of Sec. 6.1.6, evaluated on many samples at once, each
//! carrying its value and, optionally, forward-mode tangents.
//!
//! A sample occupies `c` consecutive columns of an activation matrix: column
//! 0 is the value, columns `1..c` are tangents `d(activation)/d(input_j)`. A
//! linear layer maps every column with the same weight and adds the bias to
//! value columns only; an activation `h = sigma(z)` takes its slope
//! `sigma'(z)` from the value column and scales the tangents by it. So the
//! network's output tangents are its Jacobian with respect to the input,
//! computed with ordinary matrix products.
//!
//! The backward pass differentiates that whole computation, tangents
//! included, so it gives exact gradients of a loss that reads the Jacobian
//! (the dEKF's `F` and `H`). Through an activation the tangent `dh_j =
//! sigma'(z) dz_j` depends on `z` too: the value column's adjoint gets the
//! second-order term `sum_j sigma''(z) dz_j g(dh_j)` besides `sigma'(z) g(h)`.
//! For ReLU `sigma'' = 0` (its slope is piecewise constant, as PyTorch's
//! double backward treats it) and the term is not computed; for smooth
//! activations (tanh, GELU) it is kept on the tape and added.
//!
//! The network is the ordered list of layers of [`NetAt::layers`] (its one
//! description, in `params.rs`): [`forward`] runs it first to last and
//! [`backward`] last to first.

use nalgebra::{DMatrix, DMatrixView, Dyn, MatrixView};

use super::params::{Activation, Layer, LinearAt, NetAt};
use super::thin::{self, Dims};

/// A matrix view with arbitrary strides.
type Strided<'a> = MatrixView<'a, f32, Dyn, Dyn, Dyn, Dyn>;

/// nalgebra hands a product to `matrixmultiply` (which honours any strides)
/// only when every dimension exceeds 5; below that its fallback needs
/// contiguous columns, so strided views are used only above this size.
fn blas_sized(dims: &[usize]) -> bool {
    dims.iter().all(|&d| d > 5)
}

/// Products with at most this many columns (parts of 1 or 2 windows: 3
/// columns each through the networks with tangents, 1 through the feature
/// network) go to the register-blocked kernels of [`thin`]; wider ones to
/// nalgebra (`matrixmultiply`), whose packing pays off there. Per column of
/// a 64 x 64 layer (`time_the_thin_products`, release, AVX2+FMA): `W x`
/// 160 ns against 410-540 (nalgebra, 1-3 columns), 160 at 12 columns; `W^T dy`
/// 440 against 1200 (1-3) and 530 (6), 280 at 12 for nalgebra; `dy x^T`
/// 115 against 340 (3), the same at 12.
pub const THIN_COLUMNS: usize = 6;

/// The shapes of `l` applied to `n` columns, when they are thin.
fn thin_dims(l: &LinearAt, n: usize) -> Option<Dims> {
    (n <= THIN_COLUMNS).then_some(Dims { out: l.out, inp: l.inp, n })
}

/// What the backward pass needs of one activation.
struct ActivationTape {
    /// `sigma'(z)` of each sample's value column (`rows x samples`; for ReLU
    /// the 0/1 mask).
    slope: DMatrix<f32>,
    /// `sigma''(z) dz_j` in each tangent column, 0 in value columns
    /// (`rows x n`); `None` when it is zero everywhere (ReLU, or no tangents).
    curvature: Option<DMatrix<f32>>,
}

/// The activations a backward pass needs: the input of every linear layer
/// (in layer order) and what every activation's derivative needs.
pub struct Tape {
    inputs: Vec<DMatrix<f32>>,
    activations: Vec<ActivationTape>,
    cols: usize,
}

/// `tanh` and its first two derivatives at `z`.
#[inline]
fn tanh3(z: f32) -> (f32, f32, f32) {
    let a = z.tanh();
    let d1 = 1.0 - a * a;
    (a, d1, -2.0 * a * d1)
}

/// GELU (tanh approximation) and its first two derivatives at `z`:
/// `g = x (1 + t) / 2`, `t = tanh(u)`, `u = c (x + k x^3)`;
/// `g' = (1 + t) / 2 + x (1 - t^2) u' / 2`;
/// `g'' = (1 - t^2) (u' + x (u'' - 2 t u'^2) / 2)`.
#[inline]
fn gelu3(z: f32) -> (f32, f32, f32) {
    const C: f32 = 0.797_884_6; // sqrt(2 / pi)
    const K: f32 = 0.044_715;
    let z2 = z * z;
    let t = (C * (z + K * z2 * z)).tanh();
    let sech2 = 1.0 - t * t;
    let du = C * (1.0 + 3.0 * K * z2);
    let ddu = 6.0 * C * K * z;
    let a = 0.5 * z * (1.0 + t);
    let d1 = 0.5 * (1.0 + t) + 0.5 * z * sech2 * du;
    let d2 = sech2 * (du + 0.5 * z * (ddu - 2.0 * t * du * du));
    (a, d1, d2)
}

/// `act` and its first two derivatives at `z` (ReLU: `max(z, 0)`, slope 0 at
/// 0 and below, no curvature). For tests and one-off use: the loops below
/// dispatch on the activation once, outside their inner loops.
pub fn activation3(act: Activation, z: f32) -> (f32, f32, f32) {
    match act {
        Activation::Relu => {
            let m = if z > 0.0 { 1.0 } else { 0.0 };
            (z * m, m, 0.0)
        }
        Activation::Tanh => tanh3(z),
        Activation::Gelu => gelu3(z),
    }
}

/// Applies `act` to the vector `v` in place and writes its slope
/// `sigma'(v)` into `slope` (the online path's single sample).
pub(super) fn activate_vector(act: Activation, v: &mut [f32], slope: &mut [f32]) {
    fn each(v: &mut [f32], slope: &mut [f32], f: impl Fn(f32) -> (f32, f32, f32)) {
        for (x, s) in v.iter_mut().zip(slope.iter_mut()) {
            let (a, d1, _) = f(*x);
            *x = a;
            *s = d1;
        }
    }
    match act {
        Activation::Relu => {
            for (x, s) in v.iter_mut().zip(slope.iter_mut()) {
                *s = if *x > 0.0 { 1.0 } else { 0.0 };
                *x *= *s;
            }
        }
        Activation::Tanh => each(v, slope, tanh3),
        Activation::Gelu => each(v, slope, gelu3),
    }
}

/// The weight of `l` as an `out x in` matrix (stored column-major).
fn weight<'a>(p: &'a [f32], l: &LinearAt) -> DMatrixView<'a, f32> {
    DMatrixView::from_slice(&p[l.weight..l.weight + l.out * l.inp], l.out, l.inp)
}

/// `y = W x` on every column, plus the bias on value columns.
fn linear(p: &[f32], l: &LinearAt, x: &DMatrix<f32>, cols: usize) -> DMatrix<f32> {
    let mut y = DMatrix::<f32>::zeros(l.out, x.ncols());
    match thin_dims(l, x.ncols()) {
        Some(d) => thin::mul(&p[l.weight..l.weight + l.out * l.inp], d, x.as_slice(), y.as_mut_slice()),
        None => y.gemm(1.0, &weight(p, l), x, 0.0),
    }
    let bias = &p[l.bias..l.bias + l.out];
    for s in (0..x.ncols()).step_by(cols) {
        for (v, b) in y.column_mut(s).iter_mut().zip(bias) {
            *v += b;
        }
    }
    y
}

/// ReLU with the value column's mask on every column of the sample.
fn relu(y: &mut DMatrix<f32>, cols: usize) -> ActivationTape {
    let rows = y.nrows();
    let samples = y.ncols() / cols;
    let mut mask = DMatrix::<f32>::zeros(rows, samples);
    for (block, m) in
        y.as_mut_slice().chunks_exact_mut(rows * cols).zip(mask.as_mut_slice().chunks_exact_mut(rows))
    {
        let (value, tangents) = block.split_at_mut(rows);
        for (v, mi) in value.iter_mut().zip(m.iter_mut()) {
            *mi = if *v > 0.0 { 1.0 } else { 0.0 };
            *v *= *mi;
        }
        for t in tangents.chunks_exact_mut(rows) {
            for (ti, mi) in t.iter_mut().zip(m.iter()) {
                *ti *= mi;
            }
        }
    }
    ActivationTape { slope: mask, curvature: None }
}

/// A smooth activation `f` (value, slope, curvature at `z`) on every sample:
/// the value column becomes `sigma(z)`, tangent `j` becomes `sigma'(z) dz_j`,
/// and `sigma''(z) dz_j` is kept for the backward pass.
fn smooth(y: &mut DMatrix<f32>, cols: usize, f: impl Fn(f32) -> (f32, f32, f32)) -> ActivationTape {
    let rows = y.nrows();
    let samples = y.ncols() / cols;
    let mut slope = DMatrix::<f32>::zeros(rows, samples);
    let mut curvature = (cols > 1).then(|| DMatrix::<f32>::zeros(rows, y.ncols()));
    let mut second = vec![0.0f32; rows];
    for (s, block) in y.as_mut_slice().chunks_exact_mut(rows * cols).enumerate() {
        let (value, tangents) = block.split_at_mut(rows);
        let d1 = &mut slope.as_mut_slice()[s * rows..(s + 1) * rows];
        for ((v, d), dd) in value.iter_mut().zip(d1.iter_mut()).zip(second.iter_mut()) {
            (*v, *d, *dd) = f(*v);
        }
        let Some(curv) = curvature.as_mut() else { continue };
        let curv = &mut curv.as_mut_slice()[s * rows * cols..(s + 1) * rows * cols];
        for (t, c) in tangents.chunks_exact_mut(rows).zip(curv[rows..].chunks_exact_mut(rows)) {
            for (((ti, ci), d), dd) in t.iter_mut().zip(c.iter_mut()).zip(d1.iter()).zip(&second) {
                *ci = dd * *ti;
                *ti *= d;
            }
        }
    }
    ActivationTape { slope, curvature }
}

/// Applies `act` to `y` (every sample's value and tangents).
fn activate(act: Activation, y: &mut DMatrix<f32>, cols: usize) -> ActivationTape {
    match act {
        Activation::Relu => relu(y, cols),
        Activation::Tanh => smooth(y, cols, tanh3),
        Activation::Gelu => smooth(y, cols, gelu3),
    }
}

/// Turns `d`, the adjoint of an activation's output (every column), into
/// the adjoint of its input: tangent columns `sigma'(z) g(dh_j)`, the value
/// column `sigma'(z) g(h) + sum_j sigma''(z) dz_j g(dh_j)`.
fn activation_backward(d: &mut DMatrix<f32>, tape: &ActivationTape, cols: usize) {
    let rows = tape.slope.nrows();
    let slopes = tape.slope.as_slice().chunks_exact(rows);
    for (s, (block, m)) in d.as_mut_slice().chunks_exact_mut(rows * cols).zip(slopes).enumerate() {
        let (value, tangents) = block.split_at_mut(rows);
        for (v, mi) in value.iter_mut().zip(m) {
            *v *= mi;
        }
        if let Some(curv) = &tape.curvature {
            // The tangents' adjoints are still those of the output here.
            let curv = &curv.as_slice()[s * rows * cols..(s + 1) * rows * cols];
            for (t, c) in tangents.chunks_exact(rows).zip(curv[rows..].chunks_exact(rows)) {
                for ((v, ti), ci) in value.iter_mut().zip(t).zip(c) {
                    *v += ci * ti;
                }
            }
        }
        for t in tangents.chunks_exact_mut(rows) {
            for (ti, mi) in t.iter_mut().zip(m) {
                *ti *= mi;
            }
        }
    }
}

/// The residual block `act(fc2(act(fc1(h))) + h)` on `h`, recording the
/// inputs of its two linear layers and its two activations.
fn residual(
    p: &[f32],
    (fc1, fc2, act): (&LinearAt, &LinearAt, Activation),
    h: DMatrix<f32>,
    tape: &mut Tape,
) -> DMatrix<f32> {
    let c = tape.cols;
    let mut a = linear(p, fc1, &h, c);
    let first = activate(act, &mut a, c);
    let mut s = linear(p, fc2, &a, c);
    s += &h;
    let second = activate(act, &mut s, c);
    tape.inputs.push(h);
    tape.inputs.push(a);
    tape.activations.push(first);
    tape.activations.push(second);
    s
}

/// Evaluates network `net` on `x` (`inputs x n`, `cols` columns per
/// sample), its layers first to last. Returns the output (`outputs x n`)
/// and, when `keep` is true, the tape.
pub fn forward(
    p: &[f32],
    net: &NetAt,
    x: DMatrix<f32>,
    cols: usize,
    keep: bool,
) -> (DMatrix<f32>, Option<Tape>) {
    let linears = net.linears().count();
    let mut tape =
        Tape { inputs: Vec::with_capacity(linears), activations: Vec::with_capacity(linears), cols };
    let mut h = x;
    for layer in &net.layers {
        h = match layer {
            Layer::Linear(l) => {
                let y = linear(p, l, &h, cols);
                tape.inputs.push(h);
                y
            }
            Layer::Activation(act) => {
                tape.activations.push(activate(*act, &mut h, cols));
                h
            }
            Layer::Residual { fc1, fc2, activation } => residual(p, (fc1, fc2, *activation), h, &mut tape),
        };
    }
    (h, keep.then_some(tape))
}

/// Accumulates `dW += dy x^T`, `db += sum of value columns of dy`, and
/// returns `dx = W^T dy` when asked.
fn linear_backward(
    p: &[f32],
    g: &mut [f32],
    l: &LinearAt,
    x: &DMatrix<f32>,
    dy: &DMatrix<f32>,
    cols: usize,
    want_dx: bool,
) -> Option<DMatrix<f32>> {
    let n = x.ncols();
    let thin = thin_dims(l, n);
    if let Some(d) = thin {
        thin::add_outer(&mut g[l.weight..l.weight + l.out * l.inp], d, dy.as_slice(), x.as_slice());
    } else {
        let mut gw =
            nalgebra::DMatrixViewMut::from_slice(&mut g[l.weight..l.weight + l.out * l.inp], l.out, l.inp);
        if blas_sized(&[l.out, l.inp, n]) {
            // x^T without a copy: column-major x read row-wise.
            let xt = Strided::from_slice_with_strides(x.as_slice(), n, l.inp, l.inp, 1);
            gw.gemm(1.0, dy, &xt, 1.0);
        } else {
            gw.gemm(1.0, dy, &x.transpose(), 1.0);
        }
    }
    for s in (0..n).step_by(cols) {
        for (gb, d) in g[l.bias..l.bias + l.out].iter_mut().zip(dy.column(s).iter()) {
            *gb += d;
        }
    }
    want_dx.then(|| {
        let mut dx = DMatrix::<f32>::zeros(l.inp, n);
        if let Some(d) = thin {
            thin::mul_transposed(&p[l.weight..l.weight + l.out * l.inp], d, dy.as_slice(), dx.as_mut_slice());
        } else if blas_sized(&[l.out, l.inp, n]) {
            // W^T without a copy: the column-major weight read row-wise.
            let w = &p[l.weight..l.weight + l.out * l.inp];
            let wt = Strided::from_slice_with_strides(w, l.inp, l.out, l.out, 1);
            dx.gemm(1.0, &wt, dy, 0.0);
        } else {
            dx.gemm_tr(1.0, &weight(p, l), dy, 0.0);
        }
        dx
    })
}

/// Backpropagates `dy` (`outputs x n`, the loss gradient of every output
/// column, values and tangents) through the network's layers, last to
/// first, accumulating parameter gradients into `g`. With `want_input`,
/// returns the gradient with respect to the input (`inputs x n`; the value
/// columns are the loss's gradient with respect to the input `x`,
/// second-order terms of the tangents included).
pub fn backward(
    p: &[f32],
    g: &mut [f32],
    net: &NetAt,
    tape: &Tape,
    dy: &DMatrix<f32>,
    want_input: bool,
) -> Option<DMatrix<f32>> {
    let c = tape.cols;
    // The tape in the order it was written, read from its end.
    let mut inputs = tape.inputs.iter().rev();
    let mut acts = tape.activations.iter().rev();
    let mut recorded = || inputs.next().expect("the tape of this network");
    let mut d: Option<DMatrix<f32>> = None;
    for (i, layer) in net.layers.iter().enumerate().rev() {
        // The input's gradient of the first layer only when asked for.
        let want_dx = i > 0 || want_input;
        let dh = d.take();
        d = match layer {
            Layer::Linear(l) => linear_backward(p, g, l, recorded(), dh.as_ref().unwrap_or(dy), c, want_dx),
            Layer::Activation(_) => {
                let mut dh = dh.unwrap_or_else(|| dy.clone());
                activation_backward(&mut dh, acts.next().expect("the tape of this network"), c);
                Some(dh)
            }
            Layer::Residual { fc1, fc2, .. } => {
                let mut dh = dh.unwrap_or_else(|| dy.clone());
                let (second, first) = (acts.next(), acts.next());
                let (ain, hin) = (recorded(), recorded());
                activation_backward(&mut dh, second.expect("the tape of this network"), c);
                let mut da = linear_backward(p, g, fc2, ain, &dh, c, true).unwrap_or_default();
                activation_backward(&mut da, first.expect("the tape of this network"), c);
                let dskip = linear_backward(p, g, fc1, hin, &da, c, true).unwrap_or_default();
                dh += dskip;
                Some(dh)
            }
        };
    }
    d.filter(|_| want_input)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::dekf::params::{Architecture, Layout};
    use rand::{RngExt, SeedableRng};

    /// The architectures every check runs on: the thesis's, two shared
    /// blocks with tanh, one with GELU, and ReLU without shared blocks;
    /// widths that are not multiples of 8 exercise the remainders.
    pub(crate) fn architectures() -> Vec<Architecture> {
        vec![
            Architecture::default(),
            Architecture { width: 20, residual_blocks: 2, activation: Activation::Tanh },
            Architecture { width: 13, residual_blocks: 1, activation: Activation::Gelu },
            Architecture { width: 9, residual_blocks: 0, activation: Activation::Relu },
        ]
    }

    /// True when two evaluations took the same ReLU branches everywhere (so a
    /// finite difference between them does not straddle a kink); always true
    /// for smooth activations.
    fn same_branches(a: &Tape, b: &Tape) -> bool {
        a.activations.iter().zip(&b.activations).all(|(x, y)| x.curvature.is_some() || x.slope == y.slope)
    }

    fn setup(arch: &Architecture, seed: u64) -> (Layout, Vec<f32>) {
        let layout = Layout::with_architecture(3, arch);
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
        let mut p = layout.init(&mut rng);
        // Larger biases than PyTorch's initialisation: activations away from
        // their linear region, so that the curvature terms matter.
        for net in [&layout.motion, &layout.measurement, &layout.feature] {
            for l in net.linears() {
                for b in &mut p[l.bias..l.bias + l.out] {
                    *b *= 3.0;
                }
            }
        }
        (layout, p)
    }

    /// Value and tangent columns for samples at states `x`.
    fn with_tangents(xs: &[[f32; 2]]) -> DMatrix<f32> {
        let mut m = DMatrix::<f32>::zeros(2, 3 * xs.len());
        for (s, x) in xs.iter().enumerate() {
            m[(0, 3 * s)] = x[0];
            m[(1, 3 * s)] = x[1];
            m[(0, 3 * s + 1)] = 1.0;
            m[(1, 3 * s + 2)] = 1.0;
        }
        m
    }

    fn random_states(rng: &mut rand::rngs::StdRng, n: usize) -> Vec<[f32; 2]> {
        (0..n).map(|_| [rng.random_range(-3.0..3.0), rng.random_range(-3.0..3.0)]).collect()
    }

    #[test]
    fn the_activations_derivatives_match_finite_differences() {
        for act in Activation::ALL {
            for k in 0..200 {
                let z = -4.0 + 8.0 * (k as f32 + 0.37) / 200.0;
                let (a, d1, d2) = activation3(act, z);
                let f = |x: f64| f64::from(activation3(act, x as f32).0);
                let g = |x: f64| f64::from(activation3(act, x as f32).1);
                let (z, eps) = (f64::from(z), 1e-2);
                if act == Activation::Relu && z.abs() < 2.0 * eps {
                    continue;
                }
                assert!((f(z) - f64::from(a)).abs() < 1e-6);
                let fd1 = (f(z + eps) - f(z - eps)) / (2.0 * eps);
                let fd2 = (g(z + eps) - g(z - eps)) / (2.0 * eps);
                assert!((fd1 - f64::from(d1)).abs() < 1e-3, "{act:?} at {z}: slope {d1} vs {fd1}");
                assert!((fd2 - f64::from(d2)).abs() < 1e-3, "{act:?} at {z}: curvature {d2} vs {fd2}");
            }
        }
        // GELU's tanh approximation at known points.
        let (g1, _, _) = activation3(Activation::Gelu, 1.0);
        assert!((g1 - 0.841_192).abs() < 1e-5, "{g1}");
    }

    #[test]
    fn tangent_columns_are_the_jacobian() {
        for arch in architectures() {
            let (layout, p) = setup(&arch, 7);
            let x = random_states(&mut rand::rngs::StdRng::seed_from_u64(11), 6);
            let (y, _) = forward(&p, &layout.motion, with_tangents(&x), 3, false);
            let (mut checked, mut skipped) = (0, 0);
            for (s, xs) in x.iter().enumerate() {
                for j in 0..2 {
                    let eps = 1e-3f32;
                    let (mut up, mut down) = (*xs, *xs);
                    up[j] += eps;
                    down[j] -= eps;
                    let f = |v: [f32; 2]| forward(&p, &layout.motion, with_tangents(&[v]), 3, true);
                    let ((yu, tu), (yd, td)) = (f(up), f(down));
                    if !same_branches(&tu.unwrap(), &td.unwrap()) {
                        skipped += 1;
                        continue;
                    }
                    let numeric = (f64::from(yu[(0, 0)]) - f64::from(yd[(0, 0)])) / (2.0 * f64::from(eps));
                    let analytic = f64::from(y[(0, 3 * s + 1 + j)]);
                    assert!(
                        (numeric - analytic).abs() < 5e-3 * (1.0 + analytic.abs()),
                        "{arch:?} sample {s} input {j}: {numeric} vs {analytic}"
                    );
                    checked += 1;
                }
            }
            assert!(skipped <= 2, "{arch:?}: {skipped} of {} derivatives straddle a kink", checked + skipped);
        }
    }

    /// `loss = sum over output columns of w * output` (values and tangents).
    fn weighted(p: &[f32], net: &NetAt, x: &[[f32; 2]], w: &[f32]) -> (f64, Tape) {
        let (y, tape) = forward(p, net, with_tangents(x), 3, true);
        (y.iter().zip(w).map(|(a, b)| f64::from(*a) * f64::from(*b)).sum(), tape.unwrap())
    }

    /// Every tensor of every network, at random elements, random inputs and
    /// random parameters from three seeds: the backward pass of a loss that
    /// reads values and Jacobians against central differences. Elements
    /// whose difference crosses a ReLU kink are skipped, counted, and may be
    /// at most 5 % of the candidates.
    #[test]
    fn parameter_gradients_of_values_and_jacobians_match_finite_differences() {
        for arch in architectures() {
            let (mut checked, mut skipped, mut nonzero) = (0usize, 0usize, 0usize);
            for seed in [1u64, 2, 3] {
                let (layout, p) = setup(&arch, seed);
                let mut rng = rand::rngs::StdRng::seed_from_u64(100 + seed);
                let x = random_states(&mut rng, 3);
                let w: Vec<f32> = (0..9).map(|_| rng.random_range(-1.5..1.5)).collect();
                for net in [&layout.motion, &layout.measurement] {
                    let (_, tape) = weighted(&p, net, &x, &w);
                    let mut g = vec![0.0f32; layout.len];
                    backward(&p, &mut g, net, &tape, &DMatrix::from_row_slice(1, 9, &w), false);
                    for l in net.linears() {
                        let weights = l.weight..l.weight + l.out * l.inp;
                        let biases = l.bias..l.bias + l.out;
                        for range in [weights, biases] {
                            for _ in 0..3 {
                                let idx = rng.random_range(range.clone());
                                // Small steps for ReLU (fewer kinks crossed),
                                // larger ones for smooth activations (less
                                // f32 noise; the truncation error is O(eps^2)).
                                let eps = if arch.activation.has_curvature() { 1e-2f32 } else { 1e-3 };
                                let (mut up, mut down) = (p.clone(), p.clone());
                                up[idx] += eps;
                                down[idx] -= eps;
                                let ((lu, tu), (ld, td)) =
                                    (weighted(&up, net, &x, &w), weighted(&down, net, &x, &w));
                                if !same_branches(&tu, &td) {
                                    skipped += 1;
                                    continue;
                                }
                                let numeric = (lu - ld) / (2.0 * f64::from(eps));
                                let analytic = f64::from(g[idx]);
                                assert!(
                                    (numeric - analytic).abs() < 3e-3 * (1.0 + analytic.abs()),
                                    "{arch:?} seed {seed} param {idx}: {numeric} vs {analytic}"
                                );
                                checked += 1;
                                nonzero += usize::from(analytic.abs() > 1e-4);
                            }
                        }
                    }
                }
            }
            let total = checked + skipped;
            assert!(skipped * 20 <= total, "{arch:?}: {skipped} of {total} candidates straddle a kink");
            assert!(nonzero * 2 >= checked, "{arch:?}: only {nonzero} of {checked} gradients are not zero");
        }
    }

    /// The gradient with respect to the input of a loss that reads the
    /// Jacobian holds the network's Hessian: zero for ReLU, not for smooth
    /// activations. Without the curvature terms the smooth networks fail.
    #[test]
    fn input_gradients_include_the_second_order_terms() {
        for arch in architectures() {
            let (layout, p) = setup(&arch, 5);
            let net = &layout.measurement;
            let mut rng = rand::rngs::StdRng::seed_from_u64(9);
            let x = random_states(&mut rng, 4);
            let w: Vec<f32> = (0..12).map(|_| rng.random_range(-1.5..1.5)).collect();
            // The value columns' weights zero: only the Jacobian is read.
            let w: Vec<f32> = w.iter().enumerate().map(|(i, v)| if i % 3 == 0 { 0.0 } else { *v }).collect();
            let (_, tape) = weighted(&p, net, &x, &w);
            let mut g = vec![0.0f32; layout.len];
            let dx = backward(&p, &mut g, net, &tape, &DMatrix::from_row_slice(1, 12, &w), true).unwrap();
            let mut largest = 0.0f64;
            for s in 0..x.len() {
                for j in 0..2 {
                    let eps = 1e-2f32;
                    let (mut up, mut down) = (x.clone(), x.clone());
                    up[s][j] += eps;
                    down[s][j] -= eps;
                    let ((lu, tu), (ld, td)) = (weighted(&p, net, &up, &w), weighted(&p, net, &down, &w));
                    let numeric = (lu - ld) / (2.0 * f64::from(eps));
                    let analytic = f64::from(dx[(j, 3 * s)]);
                    largest = largest.max(analytic.abs());
                    if same_branches(&tu, &td) {
                        assert!(
                            (numeric - analytic).abs() < 3e-3 * (1.0 + analytic.abs()),
                            "{arch:?} sample {s} input {j}: {numeric} vs {analytic}"
                        );
                    }
                }
            }
            if arch.activation.has_curvature() {
                assert!(largest > 0.01, "{arch:?}: second-order input gradient {largest}");
            } else {
                assert_eq!(largest, 0.0, "{arch:?}: a ReLU network's Jacobian is piecewise constant");
            }
        }
    }
}
