//! Fast evaluation of one sample (the online path): the second executor of
//! a network's list of layers ([`NetAt::layers`], the first being the
//! batched pass of [`super::mlp`]). The list is compiled once, when the
//! network is built, into steps that read and write slots of one buffer;
//! every buffer is allocated then, none in a step.
//!
//! A network's value is one forward pass; the gradient of its scalar output
//! with respect to a two-dimensional input (the Jacobians `F` and `H` of the
//! dEKF) is one reverse pass over the same steps, cheaper than carrying two
//! tangent columns forward. Weights are kept column by column (the
//! parameters' own layout), so the forward product is a sum of scaled
//! columns that the compiler vectorises and that skips the inputs an
//! activation zeroed, and the reverse product is a dot product per column,
//! skipped where the slope of the activation that made the input is zero
//! (for ReLU, wherever it zeroed its input). The activation is dispatched
//! once per layer, outside the inner loops.

use std::ops::Range;

use super::mlp::activate_vector;
use super::params::{Activation, Layer, LinearAt, NetAt};

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

    /// Number of outputs.
    fn outputs(&self) -> usize {
        self.bias.len()
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

/// Where a step reads its input.
#[derive(Clone, Debug)]
enum Source {
    /// The network's input.
    Input,
    /// A slot of the value buffer.
    Slot {
        /// Its place in the buffer.
        at: Range<usize>,
        /// True when an activation wrote it, so that its slopes are kept
        /// (at the same place in the slope buffer).
        activated: bool,
    },
}

/// One layer of the network, compiled.
#[derive(Clone, Debug)]
enum Step {
    /// A linear layer writing slot `to`.
    Linear { layer: Wide, from: Source, to: Range<usize> },
    /// An activation on slot `at`, in place, its slopes kept.
    Activation { activation: Activation, at: Range<usize> },
    /// A residual block on slot `from`: `a = act(fc1 h)` in slot `a`, the
    /// output `act(fc2 a + h)` in the slot after it.
    Residual {
        fc1: Wide,
        fc2: Wide,
        activation: Activation,
        from: Range<usize>,
        from_activated: bool,
        a: Range<usize>,
    },
    /// The last layer, with one output: `weight . h + bias`.
    Output { weight: Vec<f32>, bias: f32, from: Range<usize> },
}

/// One network with one output and scratch space for a forward and a
/// reverse pass: the steps of its layers, and a value and a slope buffer
/// with a slot for every layer's output (an activation works in place).
#[derive(Clone, Debug)]
pub struct FastNet {
    steps: Vec<Step>,
    /// Activation values by slot.
    values: Vec<f32>,
    /// The activation's slope at every value of an activated slot.
    slopes: Vec<f32>,
    /// Gradient scratch: four vectors of the largest width.
    scratch: Vec<f32>,
    /// The largest width of a layer.
    width: usize,
}

/// The slot `(at, activated)` of `from`, or `None` for the input.
fn slot(from: &Source) -> Option<(&Range<usize>, bool)> {
    match from {
        Source::Input => None,
        Source::Slot { at, activated } => Some((at, *activated)),
    }
}

impl FastNet {
    /// Compiles network `net` (its layers, with the parameters `p`). The
    /// last layer must be linear with one output and only linear layers may
    /// read the network's input (as in every network of a sliding model).
    pub fn new(p: &[f32], net: &NetAt) -> FastNet {
        let (mut steps, mut len, mut width) = (Vec::with_capacity(net.layers.len()), 0, 0);
        let mut current = Source::Input;
        let mut new_slot = |n: usize| {
            width = width.max(n);
            len += n;
            len - n..len
        };
        let last = net.layers.len() - 1;
        for (i, layer) in net.layers.iter().enumerate() {
            let slot_of = |current: &Source| match current {
                Source::Slot { at, activated } => (at.clone(), *activated),
                Source::Input => unreachable!("layer {i} reads the input: only a linear layer may"),
            };
            match layer {
                Layer::Linear(l) if i == last => {
                    assert_eq!(l.out, 1, "the fast path is for networks with one output");
                    let from = slot_of(&current).0;
                    // [1, inp] column-major: one weight per input, contiguous.
                    steps.push(Step::Output {
                        weight: p[l.weight..l.weight + l.inp].to_vec(),
                        bias: p[l.bias],
                        from,
                    });
                }
                Layer::Linear(l) => {
                    let to = new_slot(l.out);
                    let from =
                        std::mem::replace(&mut current, Source::Slot { at: to.clone(), activated: false });
                    steps.push(Step::Linear { layer: Wide::new(p, l), from, to });
                }
                Layer::Activation(activation) => {
                    let (at, _) = slot_of(&current);
                    current = Source::Slot { at: at.clone(), activated: true };
                    steps.push(Step::Activation { activation: *activation, at });
                }
                Layer::Residual { fc1, fc2, activation } => {
                    let (from, from_activated) = slot_of(&current);
                    let a = new_slot(fc1.out);
                    let out = new_slot(fc2.out);
                    current = Source::Slot { at: out, activated: true };
                    let (fc1, fc2) = (Wide::new(p, fc1), Wide::new(p, fc2));
                    steps.push(Step::Residual { fc1, fc2, activation: *activation, from, from_activated, a });
                }
            }
        }
        FastNet {
            steps,
            values: vec![0.0; len],
            slopes: vec![0.0; len],
            scratch: vec![0.0; 4 * width],
            width,
        }
    }

    /// The network's output for `input`, keeping the activations.
    pub fn value(&mut self, input: &[f32]) -> f32 {
        let mut y = 0.0;
        for step in &self.steps {
            let values = &mut self.values;
            match step {
                Step::Linear { layer, from, to } => {
                    let (lo, hi) = values.split_at_mut(to.start);
                    let x = slot(from).map_or(input, |(at, _)| &lo[at.clone()]);
                    layer.forward(x, &mut hi[..to.len()]);
                }
                Step::Activation { activation, at } => {
                    activate_vector(*activation, &mut values[at.clone()], &mut self.slopes[at.clone()]);
                }
                Step::Residual { fc1, fc2, activation, from, a, .. } => {
                    // a = act(fc1 h), s = act(fc2 a + h).
                    let (lo, hi) = values.split_at_mut(a.start);
                    let h = &lo[from.clone()];
                    let (av, sv) = hi.split_at_mut(a.len());
                    let sv = &mut sv[..fc2.outputs()];
                    let slopes = &mut self.slopes[a.start..a.end + sv.len()];
                    let (sa, ss) = slopes.split_at_mut(a.len());
                    fc1.forward(h, av);
                    activate_vector(*activation, av, sa);
                    fc2.forward(av, sv);
                    for (si, hi) in sv.iter_mut().zip(h) {
                        *si += hi;
                    }
                    activate_vector(*activation, sv, ss);
                }
                Step::Output { weight, bias, from } => y = dot(weight, &values[from.clone()]) + bias,
            }
        }
        y
    }

    /// Reverse pass through a residual block: `g` holds the gradient at its
    /// output on entry and at its input on return. The input's own
    /// activation slope (when the input is an activation's output) is not
    /// applied here; the dot products it would zero are skipped.
    fn residual_back(&self, step: &Step, g: &mut [f32], ga: &mut [f32], gh: &mut [f32]) {
        let Step::Residual { fc1, fc2, from, from_activated, a, .. } = step else { return };
        let s = a.end..a.end + g.len();
        let (ga, gh) = (&mut ga[..a.len()], &mut gh[..from.len()]);
        scale(g, &self.slopes[s]);
        fc2.backward_scaled(g, &self.slopes[a.clone()], ga);
        if *from_activated {
            fc1.backward_where(ga, &self.slopes[from.clone()], gh);
        } else {
            fc1.backward(ga, gh);
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
        // The gradient at the current step's output: `cur[..n]`.
        let (mut cur, mut other, mut n) = (g, g1, 0);
        let mut gx = [0.0; 2];
        for step in self.steps.iter().rev() {
            match step {
                Step::Output { weight, .. } => {
                    n = weight.len();
                    cur[..n].copy_from_slice(weight);
                }
                Step::Activation { at, .. } => scale(&mut cur[..n], &self.slopes[at.clone()]),
                Step::Residual { .. } => self.residual_back(step, &mut cur[..n], ga, gh),
                Step::Linear { layer, from, .. } => match slot(from) {
                    None => layer.backward(&cur[..n], &mut gx),
                    Some((at, activated)) => {
                        let gx = &mut other[..at.len()];
                        if activated {
                            layer.backward_where(&cur[..n], &self.slopes[at.clone()], gx);
                        } else {
                            layer.backward(&cur[..n], gx);
                        }
                        n = at.len();
                        std::mem::swap(&mut cur, &mut other);
                    }
                },
            }
        }
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
