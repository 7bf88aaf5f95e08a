//! Fast evaluation of one sample (the online path). A network's value is one
//! forward pass; the gradient of its scalar output with respect to a
//! two-dimensional input (the Jacobians `F` and `H` of the dEKF) is one
//! reverse pass, cheaper than carrying two tangent columns forward. Weights
//! are kept column by column (the parameters' own layout), so the forward
//! product is a sum of scaled columns that the compiler vectorises and that
//! skips the inputs a ReLU zeroed, and the reverse product is a dot product
//! per column.

use super::params::{HIDDEN, LinearAt, NetAt};

type Vector = [f32; HIDDEN];

/// A linear layer with `HIDDEN` outputs: one weight column per input.
#[derive(Clone, Debug)]
struct Wide {
    columns: Vec<Vector>,
    bias: Vector,
}

impl Wide {
    fn new(p: &[f32], l: &LinearAt) -> Wide {
        debug_assert_eq!(l.out, HIDDEN);
        let columns = (0..l.inp)
            .map(|i| {
                let mut c = [0.0; HIDDEN];
                c.copy_from_slice(&p[l.weight + i * HIDDEN..l.weight + (i + 1) * HIDDEN]);
                c
            })
            .collect();
        let mut bias = [0.0; HIDDEN];
        bias.copy_from_slice(&p[l.bias..l.bias + HIDDEN]);
        Wide { columns, bias }
    }

    /// `y = W x + b`.
    fn forward(&self, x: &[f32], y: &mut Vector) {
        *y = self.bias;
        for (c, &xi) in self.columns.iter().zip(x) {
            if xi != 0.0 {
                for (yo, w) in y.iter_mut().zip(c) {
                    *yo += w * xi;
                }
            }
        }
    }

    /// `g_x = W^T g_y`.
    fn backward(&self, gy: &Vector, gx: &mut [f32]) {
        for (g, c) in gx.iter_mut().zip(&self.columns) {
            *g = dot(c, gy);
        }
    }

    /// `g_x = W^T g_y` where the input `x` (a ReLU's output) is positive, 0
    /// elsewhere: what the ReLU would zero is not computed.
    fn backward_relu(&self, gy: &Vector, x: &Vector, gx: &mut Vector) {
        for ((g, c), xi) in gx.iter_mut().zip(&self.columns).zip(x) {
            *g = if *xi > 0.0 { dot(c, gy) } else { 0.0 };
        }
    }
}

/// `a . b` in eight lanes (vectorised), plus the elements past the last
/// whole group of eight when the width is not a multiple of it.
fn dot(a: &[f32], b: &[f32]) -> f32 {
    let mut acc = [0.0f32; 8];
    let (ca, cb) = (a.chunks_exact(8), b.chunks_exact(8));
    let tail: f32 = ca.remainder().iter().zip(cb.remainder()).map(|(x, y)| x * y).sum();
    for (ca, cb) in ca.zip(cb) {
        for l in 0..8 {
            acc[l] += ca[l] * cb[l];
        }
    }
    acc.iter().sum::<f32>() + tail
}

fn relu(y: &mut Vector) {
    for v in y.iter_mut() {
        *v = v.max(0.0);
    }
}

/// `g <- g` where the activation `a` (after a ReLU) is positive, else 0.
fn relu_back(g: &mut Vector, a: &Vector) {
    for (gi, ai) in g.iter_mut().zip(a) {
        if *ai <= 0.0 {
            *gi = 0.0;
        }
    }
}

/// One network (Sec. 6.1.6) with scratch space for a forward and a reverse pass.
#[derive(Clone, Debug)]
pub struct FastNet {
    /// Layers 0..=9 of the network: encoder linear, encoder residual (2),
    /// shared linear, three shared residuals (2 each).
    wide: Vec<Wide>,
    /// The output layer `Linear(64, 1)`: weights and bias.
    out_weight: Vector,
    out_bias: f32,
    /// Activations kept for the reverse pass: `[h0, a1, h1, h2, a3, h3, a4, h4, a5, h5]`.
    acts: [Vector; 10],
}

impl FastNet {
    /// Copies network `net` out of the flat parameters `p`.
    pub fn new(p: &[f32], net: &NetAt) -> FastNet {
        let wide = net.layers[..10].iter().map(|l| Wide::new(p, l)).collect();
        let out = &net.layers[10];
        let mut out_weight = [0.0; HIDDEN];
        // [1, 64] column-major: one weight per input, contiguous.
        out_weight.copy_from_slice(&p[out.weight..out.weight + HIDDEN]);
        FastNet { wide, out_weight, out_bias: p[out.bias], acts: [[0.0; HIDDEN]; 10] }
    }

    /// The network's output for `input`, keeping the activations.
    pub fn value(&mut self, input: &[f32]) -> f32 {
        let [h0, a1, h1, h2, a3, h3, a4, h4, a5, h5] = &mut self.acts;
        let w = &self.wide;
        w[0].forward(input, h0);
        relu(h0);
        residual(&w[1], &w[2], h0, a1, h1);
        w[3].forward(h1, h2);
        residual(&w[4], &w[5], h2, a3, h3);
        residual(&w[6], &w[7], h3, a4, h4);
        residual(&w[8], &w[9], h4, a5, h5);
        dot(&self.out_weight, h5) + self.out_bias
    }

    /// The output and its gradient with respect to a two-dimensional input.
    pub fn value_and_gradient(&mut self, input: [f32; 2]) -> (f32, [f32; 2]) {
        let y = self.value(&input);
        let [h0, a1, h1, _, a3, h3, a4, h4, a5, h5] = &self.acts;
        let w = &self.wide;
        let mut g = self.out_weight;
        residual_back(&w[8], &w[9], &mut g, a5, h5, Some(h4));
        residual_back(&w[6], &w[7], &mut g, a4, h4, Some(h3));
        residual_back(&w[4], &w[5], &mut g, a3, h3, None);
        let mut g1 = [0.0; HIDDEN];
        w[3].backward_relu(&g, h1, &mut g1);
        residual_back(&w[1], &w[2], &mut g1, a1, h1, Some(h0));
        relu_back(&mut g1, h0);
        let mut gx = [0.0; 2];
        w[0].backward(&g1, &mut gx);
        (y, gx)
    }
}

/// A residual block: `a = relu(A h)`, `s = relu(B a + h)`.
fn residual(first: &Wide, second: &Wide, h: &Vector, a: &mut Vector, s: &mut Vector) {
    first.forward(h, a);
    relu(a);
    second.forward(a, s);
    for (si, hi) in s.iter_mut().zip(h) {
        *si += hi;
    }
    relu(s);
}

/// Reverse pass through a residual block whose activations were `a` and
/// `s`: `g` holds the gradient at `s` on entry and at the block's input `h`
/// on return. When `h` is itself a ReLU's output (`relu_input`), the caller
/// zeroes the gradient where it is not positive, so it is not computed there.
fn residual_back(
    first: &Wide,
    second: &Wide,
    g: &mut Vector,
    a: &Vector,
    s: &Vector,
    relu_input: Option<&Vector>,
) {
    relu_back(g, s);
    let mut ga = [0.0; HIDDEN];
    second.backward_relu(g, a, &mut ga);
    let mut gh = [0.0; HIDDEN];
    match relu_input {
        Some(h) => first.backward_relu(&ga, h, &mut gh),
        None => first.backward(&ga, &mut gh),
    }
    for (gi, x) in g.iter_mut().zip(&gh) {
        *gi += x;
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn dot_counts_the_elements_past_the_last_group_of_eight() {
        let a: Vec<f32> = (0..13).map(|i| i as f32 * 0.5 - 2.0).collect();
        let b: Vec<f32> = (0..13).map(|i| 1.0 + i as f32).collect();
        let naive: f32 = a.iter().zip(&b).map(|(x, y)| x * y).sum();
        assert!((super::dot(&a, &b) - naive).abs() < 1e-4, "{} vs {naive}", super::dot(&a, &b));
    }

    use super::*;
    use crate::dekf::mlp::forward;
    use crate::dekf::params::Layout;
    use nalgebra::DMatrix;
    use rand::SeedableRng;

    #[test]
    fn the_fast_path_equals_the_batched_forward_with_tangents() {
        let layout = Layout::new(6);
        let p = layout.init(&mut rand::rngs::StdRng::seed_from_u64(3));
        let mut fast = FastNet::new(&p, &layout.motion);
        for x in [[0.7f32, -0.4], [-2.0, 3.0], [0.0, 0.0], [5.0, 0.5]] {
            let mut m = DMatrix::<f32>::zeros(2, 3);
            m[(0, 0)] = x[0];
            m[(1, 0)] = x[1];
            m[(0, 1)] = 1.0;
            m[(1, 2)] = 1.0;
            let (y, _) = forward(&p, &layout.motion, m, 3, false);
            let (v, g) = fast.value_and_gradient(x);
            for (c, f) in [v, g[0], g[1]].into_iter().enumerate() {
                let r = y[(0, c)];
                assert!((f - r).abs() < 1e-5 * (1.0 + r.abs()), "{x:?} column {c}: {f} vs {r}");
            }
        }
        let mut fast3 = FastNet::new(&p, &layout.feature);
        let z = [0.1f32, -2.0, 0.3, 1.5, -0.2, 0.9];
        let (y3, _) = forward(&p, &layout.feature, DMatrix::from_column_slice(6, 1, &z), 1, false);
        assert!((fast3.value(&z) - y3[(0, 0)]).abs() < 1e-5);
    }
}
