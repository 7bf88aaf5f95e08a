//! The residual MLP of Sec. 6.1.6, evaluated on many samples at once, each
//! carrying its value and, optionally, forward-mode tangents.
//!
//! A sample occupies `c` consecutive columns of an activation matrix: column
//! 0 is the value, columns `1..c` are tangents `d(activation)/d(input_j)`. A
//! linear layer maps every column with the same weight and adds the bias to
//! value columns only; a ReLU takes its mask from the value column and
//! applies it to the tangents too. So the network's output tangents are its
//! Jacobian with respect to the input, computed with ordinary matrix
//! products, and backpropagating through them gives exact parameter
//! gradients of the Jacobian (the ReLU mask is piecewise constant; PyTorch's
//! double backward treats it the same way).
//!
//! Network: `h0 = relu(encoder.linear(x))`, `h1 = res(h0)`,
//! `h2 = shared.linear(h1)`, `h3..h5 = res(...)`, `y = shared.out(h5)`,
//! with `res(h) = relu(fc2(relu(fc1(h))) + h)`.

use nalgebra::{DMatrix, DMatrixView, Dyn, MatrixView};

/// A matrix view with arbitrary strides.
type Strided<'a> = MatrixView<'a, f32, Dyn, Dyn, Dyn, Dyn>;

/// nalgebra hands a product to `matrixmultiply` (which honours any strides)
/// only when every dimension exceeds 5; below that its fallback needs
/// contiguous columns, so strided views are used only above this size.
fn blas_sized(dims: &[usize]) -> bool {
    dims.iter().all(|&d| d > 5)
}

use super::params::{LinearAt, NetAt};

/// The activations a backward pass needs: the input of every linear layer
/// and the mask of every ReLU (one column per sample).
pub struct Tape {
    inputs: Vec<DMatrix<f32>>,
    masks: Vec<DMatrix<f32>>,
    cols: usize,
}

/// The weight of `l` as an `out x in` matrix (stored column-major).
fn weight<'a>(p: &'a [f32], l: &LinearAt) -> DMatrixView<'a, f32> {
    DMatrixView::from_slice(&p[l.weight..l.weight + l.out * l.inp], l.out, l.inp)
}

/// `y = W x` on every column, plus the bias on value columns.
fn linear(p: &[f32], l: &LinearAt, x: &DMatrix<f32>, cols: usize) -> DMatrix<f32> {
    let mut y = DMatrix::<f32>::zeros(l.out, x.ncols());
    y.gemm(1.0, &weight(p, l), x, 0.0);
    let bias = &p[l.bias..l.bias + l.out];
    for s in (0..x.ncols()).step_by(cols) {
        for (v, b) in y.column_mut(s).iter_mut().zip(bias) {
            *v += b;
        }
    }
    y
}

/// ReLU with the value column's mask on every column of the sample; returns
/// the mask (one column of 0/1 per sample).
fn relu(y: &mut DMatrix<f32>, cols: usize) -> DMatrix<f32> {
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
    mask
}

/// Multiplies every column of each sample by the sample's mask.
fn apply_mask(d: &mut DMatrix<f32>, mask: &DMatrix<f32>, cols: usize) {
    let rows = mask.nrows();
    for (block, m) in d.as_mut_slice().chunks_exact_mut(rows * cols).zip(mask.as_slice().chunks_exact(rows)) {
        for col in block.chunks_exact_mut(rows) {
            for (x, mi) in col.iter_mut().zip(m) {
                *x *= mi;
            }
        }
    }
}

/// Evaluates network `net` on `x` (`inp x n`, `cols` columns per sample).
/// Returns the output (`1 x n`) and, when `keep` is true, the tape.
pub fn forward(
    p: &[f32],
    net: &NetAt,
    x: DMatrix<f32>,
    cols: usize,
    keep: bool,
) -> (DMatrix<f32>, Option<Tape>) {
    let l = &net.layers;
    let mut tape = Tape { inputs: Vec::with_capacity(11), masks: Vec::with_capacity(9), cols };
    let mut h = linear(p, &l[0], &x, cols);
    tape.inputs.push(x);
    tape.masks.push(relu(&mut h, cols));
    for (k, block) in [1usize, 4, 6, 8].into_iter().enumerate() {
        if k == 1 {
            let h2 = linear(p, &l[3], &h, cols);
            tape.inputs.push(std::mem::replace(&mut h, h2));
        }
        let mut a = linear(p, &l[block], &h, cols);
        let mask1 = relu(&mut a, cols);
        let mut s = linear(p, &l[block + 1], &a, cols);
        s += &h;
        let mask2 = relu(&mut s, cols);
        tape.inputs.push(h);
        tape.inputs.push(a);
        tape.masks.push(mask1);
        tape.masks.push(mask2);
        h = s;
    }
    let y = linear(p, &l[10], &h, cols);
    tape.inputs.push(h);
    (y, keep.then_some(tape))
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
    {
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
        if blas_sized(&[l.out, l.inp, n]) {
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

/// Backpropagates `dy` (`1 x n`, the loss gradient of every output column)
/// through the network, accumulating parameter gradients into `g`.
pub fn backward(p: &[f32], g: &mut [f32], net: &NetAt, tape: &Tape, dy: &DMatrix<f32>) {
    let l = &net.layers;
    let c = tape.cols;
    let inputs = &tape.inputs;
    // inputs: [x, h0, a0, h2in(=h1), h2, a1, h3, a2, h4, a3, h5]
    let mut dh = linear_backward(p, g, &l[10], &inputs[10], dy, c, true).unwrap_or_default();
    // Residual blocks in reverse: (fc1 layer, input index of the block, index of its `a`, mask indices).
    for (block, hin, ain, m1, m2) in [(8, 8, 9, 7, 8), (6, 6, 7, 5, 6), (4, 4, 5, 3, 4), (1, 1, 2, 1, 2)] {
        if block == 1 {
            // Through shared.linear (no activation) before the encoder's block.
            dh = linear_backward(p, g, &l[3], &inputs[3], &dh, c, true).unwrap_or_default();
        }
        apply_mask(&mut dh, &tape.masks[m2], c);
        let mut da = linear_backward(p, g, &l[block + 1], &inputs[ain], &dh, c, true).unwrap_or_default();
        apply_mask(&mut da, &tape.masks[m1], c);
        let dskip = linear_backward(p, g, &l[block], &inputs[hin], &da, c, true).unwrap_or_default();
        dh += dskip;
    }
    apply_mask(&mut dh, &tape.masks[0], c);
    linear_backward(p, g, &l[0], &inputs[0], &dh, c, false);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dekf::params::Layout;
    use rand::SeedableRng;

    /// True when two evaluations took the same ReLU branches everywhere (so a
    /// finite difference between them does not straddle a kink).
    fn same_masks(a: &Tape, b: &Tape) -> bool {
        a.masks.iter().zip(&b.masks).all(|(x, y)| x == y)
    }

    fn setup() -> (Layout, Vec<f32>) {
        let layout = Layout::new(3);
        let mut rng = rand::rngs::StdRng::seed_from_u64(7);
        let p = layout.init(&mut rng);
        (layout, p)
    }

    /// Value and tangent columns for two samples at states `x`.
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

    #[test]
    fn tangent_columns_are_the_jacobian() {
        let (layout, p) = setup();
        let x = [[0.3f32, -1.2], [2.0, 0.5], [-1.0, 0.1], [0.05, 3.0], [4.0, -2.0]];
        let (y, _) = forward(&p, &layout.motion, with_tangents(&x), 3, false);
        let mut checked = 0;
        for (s, xs) in x.iter().enumerate() {
            for j in 0..2 {
                let eps = 1e-3f32;
                let (mut up, mut down) = (*xs, *xs);
                up[j] += eps;
                down[j] -= eps;
                let f = |v: [f32; 2]| forward(&p, &layout.motion, with_tangents(&[v]), 3, true);
                let ((yu, tu), (yd, td)) = (f(up), f(down));
                if !same_masks(&tu.unwrap(), &td.unwrap()) {
                    continue;
                }
                let numeric = (yu[(0, 0)] - yd[(0, 0)]) / (2.0 * eps);
                let analytic = y[(0, 3 * s + 1 + j)];
                assert!((numeric - analytic).abs() < 2e-3, "sample {s} input {j}: {numeric} vs {analytic}");
                checked += 1;
            }
        }
        assert!(checked >= 7, "only {checked} of 10 derivatives away from a kink");
    }

    #[test]
    fn parameter_gradients_of_values_and_jacobians_match_finite_differences() {
        let (layout, p) = setup();
        let x = [[0.3f32, -1.2], [2.0, 0.5]];
        // loss = sum over outputs of weight * output (value and tangent columns).
        let w = DMatrix::<f32>::from_row_slice(1, 6, &[0.7, -1.3, 0.4, 1.1, 0.2, -0.9]);
        let (_, tape) = forward(&p, &layout.motion, with_tangents(&x), 3, true);
        let mut g = vec![0.0f32; layout.len];
        backward(&p, &mut g, &layout.motion, &tape.unwrap(), &w);
        let loss = |q: &[f32]| -> (f64, Tape) {
            let (y, tape) = forward(q, &layout.motion, with_tangents(&x), 3, true);
            (y.iter().zip(w.iter()).map(|(a, b)| f64::from(*a) * f64::from(*b)).sum(), tape.unwrap())
        };
        // A sample of parameters in every layer, all inside the layer (an
        // index past it reads another network's parameter: 0 against 0):
        // the first, a middle and the last weight, the first and last bias.
        let (mut checked, mut nonzero) = (0, 0);
        for l in &layout.motion.layers {
            let weights = l.inp * l.out;
            let middle = l.weight + (l.inp + 1) % weights;
            for idx in [l.weight, middle, l.weight + weights - 1, l.bias, l.bias + l.out - 1] {
                let mut up = p.clone();
                let mut down = p.clone();
                let eps = 1e-2f32;
                up[idx] += eps;
                down[idx] -= eps;
                let ((lu, tu), (ld, td)) = (loss(&up), loss(&down));
                if !same_masks(&tu, &td) {
                    continue;
                }
                let numeric = (lu - ld) / (2.0 * f64::from(eps));
                let analytic = f64::from(g[idx]);
                assert!(
                    (numeric - analytic).abs() < 2e-3 * (1.0 + analytic.abs()),
                    "param {idx}: {numeric} vs {analytic}"
                );
                checked += 1;
                nonzero += usize::from(analytic.abs() > 1e-6);
            }
        }
        let total = 5 * layout.motion.layers.len();
        assert!(checked >= total * 4 / 5, "only {checked} of {total} parameters away from a kink");
        assert!(nonzero >= checked / 2, "only {nonzero} of {checked} gradients are not zero");
    }
}
