//! Fast evaluation of one sample (the online path). A network's value is one
//! forward pass; the gradient of its scalar output with respect to a
//! two-dimensional input (the Jacobians `F` and `H` of the dEKF) is one
//! reverse pass, cheaper than carrying two tangent columns forward. Weights
//! are kept column by column (the parameters' own layout), so the forward
//! product is a sum of scaled columns that the compiler vectorises and that
//! skips the inputs an activation zeroed, and the reverse product is a dot
//! product per column, skipped where the activation's slope is zero (for
//! ReLU, wherever it zeroed its input). Any width, number of blocks and
//! activation: the activation is dispatched once per layer, outside the
//! inner loops, and every buffer is allocated when the network is built.

use super::mlp::activate_vector;
use super::params::{Activation, LinearAt, NetAt};

/// A linear layer with `width` outputs: one weight column per input.
#[derive(Clone, Debug)]
struct Wide {
    /// `inp` columns of `width` weights, one after the other.
    columns: Vec<f32>,
    bias: Vec<f32>,
}

impl Wide {
    fn new(p: &[f32], l: &LinearAt) -> Wide {
        Wide {
            columns: p[l.weight..l.weight + l.out * l.inp].to_vec(),
            bias: p[l.bias..l.bias + l.out].to_vec(),
        }
    }

    /// `y = W x + b`.
    fn forward(&self, x: &[f32], y: &mut [f32]) {
        y.copy_from_slice(&self.bias);
        for (c, &xi) in self.columns.chunks_exact(y.len()).zip(x) {
            if xi != 0.0 {
                for (yo, w) in y.iter_mut().zip(c) {
                    *yo += w * xi;
                }
            }
        }
    }

    /// `g_x = W^T g_y`.
    fn backward(&self, gy: &[f32], gx: &mut [f32]) {
        for (g, c) in gx.iter_mut().zip(self.columns.chunks_exact(gy.len())) {
            *g = dot(c, gy);
        }
    }

    /// `g_x = W^T g_y` where `slope` (of the activation that made the
    /// input) is not zero, 0 elsewhere: what the activation's backward will
    /// zero is not computed. The slope itself is applied by the caller.
    fn backward_where(&self, gy: &[f32], slope: &[f32], gx: &mut [f32]) {
        for ((g, c), s) in gx.iter_mut().zip(self.columns.chunks_exact(gy.len())).zip(slope) {
            *g = if *s != 0.0 { dot(c, gy) } else { 0.0 };
        }
    }

    /// `g_x = slope * (W^T g_y)`, skipping the dot product where the slope
    /// is zero: the gradient at an activation's input from its output's.
    fn backward_scaled(&self, gy: &[f32], slope: &[f32], gx: &mut [f32]) {
        for ((g, c), s) in gx.iter_mut().zip(self.columns.chunks_exact(gy.len())).zip(slope) {
            *g = if *s != 0.0 { s * dot(c, gy) } else { 0.0 };
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

/// `g <- g * slope` elementwise.
fn scale(g: &mut [f32], slope: &[f32]) {
    for (gi, s) in g.iter_mut().zip(slope) {
        *gi *= s;
    }
}

/// One network (Sec. 6.1.6) with scratch space for a forward and a reverse pass.
///
/// The activations are kept in slots of `width` values: 0 `h0` (encoder),
/// 1 and 2 the encoder's residual block (`a`, output), 3 `shared.linear`'s
/// output (no activation), then `a` and output of every shared block.
#[derive(Clone, Debug)]
pub struct FastNet {
    width: usize,
    activation: Activation,
    encoder: Wide,
    /// `(fc1, fc2)` of every residual block, the encoder's first.
    blocks: Vec<(Wide, Wide)>,
    shared: Wide,
    /// The output layer `Linear(width, 1)`: weights and bias.
    out_weight: Vec<f32>,
    out_bias: f32,
    /// Activation values by slot.
    values: Vec<f32>,
    /// The activation's slope at every value (slot 3: unused).
    slopes: Vec<f32>,
    /// Gradient scratch: four vectors of `width`.
    scratch: Vec<f32>,
}

/// The slots of block `k`: its input, its `a` and its output.
fn slots(k: usize) -> (usize, usize, usize) {
    match k {
        0 => (0, 1, 2),
        1 => (3, 4, 5),
        k => (2 + 2 * k - 1, 2 + 2 * k, 3 + 2 * k),
    }
}

impl FastNet {
    /// Copies network `net` out of the flat parameters `p`.
    pub fn new(p: &[f32], net: &NetAt) -> FastNet {
        let width = net.width();
        let count = net.residual_count();
        let blocks = (0..count)
            .map(|k| {
                let (a, b) = net.residual(k);
                (Wide::new(p, a), Wide::new(p, b))
            })
            .collect();
        let out = net.out();
        let slots = 2 + 2 * count;
        FastNet {
            width,
            activation: net.activation,
            encoder: Wide::new(p, net.encoder()),
            blocks,
            shared: Wide::new(p, net.shared_linear()),
            // [1, width] column-major: one weight per input, contiguous.
            out_weight: p[out.weight..out.weight + width].to_vec(),
            out_bias: p[out.bias],
            values: vec![0.0; slots * width],
            slopes: vec![0.0; slots * width],
            scratch: vec![0.0; 4 * width],
        }
    }

    /// The slot the output layer reads.
    fn last_slot(&self) -> usize {
        if self.blocks.len() == 1 { 3 } else { slots(self.blocks.len() - 1).2 }
    }

    /// Residual block `k` on its input slot: `a = act(A h)`, `s = act(B a + h)`.
    fn residual(&mut self, k: usize) {
        let w = self.width;
        let (hin, a, _) = slots(k);
        let (first, second) = &self.blocks[k];
        let (lo, hi) = self.values.split_at_mut(a * w);
        let h = &lo[hin * w..(hin + 1) * w];
        let (av, sv) = hi.split_at_mut(w);
        let sv = &mut sv[..w];
        let slopes = &mut self.slopes[a * w..(a + 2) * w];
        let (sa, ss) = slopes.split_at_mut(w);
        first.forward(h, av);
        activate_vector(self.activation, av, sa);
        second.forward(av, sv);
        for (si, hi) in sv.iter_mut().zip(h) {
            *si += hi;
        }
        activate_vector(self.activation, sv, ss);
    }

    /// The network's output for `input`, keeping the activations.
    pub fn value(&mut self, input: &[f32]) -> f32 {
        let w = self.width;
        self.encoder.forward(input, &mut self.values[..w]);
        activate_vector(self.activation, &mut self.values[..w], &mut self.slopes[..w]);
        self.residual(0);
        let (lo, hi) = self.values.split_at_mut(3 * w);
        self.shared.forward(&lo[2 * w..], &mut hi[..w]);
        for k in 1..self.blocks.len() {
            self.residual(k);
        }
        let last = self.last_slot();
        dot(&self.out_weight, &self.values[last * w..(last + 1) * w]) + self.out_bias
    }

    /// Reverse pass through residual block `k`: `g` holds the gradient at
    /// its output on entry and at its input on return. The input's own
    /// activation slope (when the input is an activation's output) is not
    /// applied here; the dot products it would zero are skipped.
    fn residual_back(&self, k: usize, g: &mut [f32], ga: &mut [f32], gh: &mut [f32]) {
        let w = self.width;
        let (hin, a, s) = slots(k);
        let (first, second) = &self.blocks[k];
        scale(g, &self.slopes[s * w..(s + 1) * w]);
        second.backward_scaled(g, &self.slopes[a * w..(a + 1) * w], ga);
        if hin == 3 {
            first.backward(ga, gh);
        } else {
            first.backward_where(ga, &self.slopes[hin * w..(hin + 1) * w], gh);
        }
        for (gi, x) in g.iter_mut().zip(gh.iter()) {
            *gi += x;
        }
    }

    /// The output and its gradient with respect to a two-dimensional input.
    pub fn value_and_gradient(&mut self, input: [f32; 2]) -> (f32, [f32; 2]) {
        let y = self.value(&input);
        let w = self.width;
        let mut scratch = std::mem::take(&mut self.scratch);
        let (g, rest) = scratch.split_at_mut(w);
        let (g1, rest) = rest.split_at_mut(w);
        let (ga, gh) = rest.split_at_mut(w);
        g.copy_from_slice(&self.out_weight);
        for k in (1..self.blocks.len()).rev() {
            self.residual_back(k, g, ga, gh);
        }
        // Through shared.linear, into the encoder block's output (slot 2).
        self.shared.backward_where(g, &self.slopes[2 * w..3 * w], g1);
        self.residual_back(0, g1, ga, gh);
        scale(g1, &self.slopes[..w]);
        let mut gx = [0.0; 2];
        self.encoder.backward(g1, &mut gx);
        self.scratch = scratch;
        (y, gx)
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
        for arch in crate::dekf::mlp::tests::architectures() {
            the_fast_path_equals_the_batched_forward(&arch);
        }
    }

    fn the_fast_path_equals_the_batched_forward(arch: &crate::dekf::params::Architecture) {
        let layout = Layout::with_architecture(6, arch);
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
                assert!((f - r).abs() < 1e-5 * (1.0 + r.abs()), "{arch:?} {x:?} column {c}: {f} vs {r}");
            }
        }
        let mut fast3 = FastNet::new(&p, &layout.feature);
        let z = [0.1f32, -2.0, 0.3, 1.5, -0.2, 0.9];
        let (y3, _) = forward(&p, &layout.feature, DMatrix::from_column_slice(6, 1, &z), 1, false);
        assert!((fast3.value(&z) - y3[(0, 0)]).abs() < 1e-5);
    }
}
