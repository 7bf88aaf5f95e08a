//! Fast evaluation of one sample (the online path): the second executor of
//! a network's list of layers ([`NetAt::layers`], the first being the
//! batched pass of [`super::mlp`]). The list is compiled once, when the
//! network is built, into steps that read and write slots of one buffer;
//! every buffer is allocated then, none in a step.
//!
//! A network's value is one forward pass; the gradient of its scalar output
//! with respect to a two-dimensional input (the Jacobians `F` and `H` of the
//! dEKF) is one reverse pass over the same steps. Each linear layer keeps
//! its weights column by column (the parameters' own layout) for the
//! forward product `W x`, a sum of scaled columns, and row by row (the
//! transpose) for the reverse product `W^T g`, a sum of scaled rows: both
//! are the one register-blocked kernel of `kernels`, which skips the zero
//! elements of the vector (the inputs a ReLU zeroed; in reverse, the
//! gradients its slope zeroed). Where the input's activation has a zero
//! slope the reverse result is zeroed, as the chain rule would. The
//! activation is dispatched once per layer, outside the inner loops.
//!
//! A whole pass runs inside one dispatch to the instruction set found when
//! the network was built (`kernels::Isa`): AVX2 with fused multiply-adds
//! where the CPU has them, the build's baseline otherwise. The two differ
//! only in rounding (the fused one rounds once per multiply-add; the sum
//! of the timing aid's 40 000 feature values differs by 2e-7 relative). On
//! the 2-core AMD EPYC of `docs/dekf.md` the three networks of one step
//! take 7.9 us with AVX2+FMA against 12.2 us without (minimum of 200 runs
//! of 200 steps,
//! `cargo test --release -p slidetrack-estimators --lib time_the_networks
//! -- --ignored --nocapture`).

use std::ops::Range;

use super::mlp::activate_vector;
use super::params::{Activation, Layer, LinearAt, NetAt};

mod kernels;

use kernels::{Fused, Isa, MulAdd, PORTABLE_BLOCK, Separate, V3_BLOCK, dot, mat_vec};

/// A linear layer with `width` outputs: its weights column by column (one
/// column per input) and row by row (one row per output).
#[derive(Clone, Debug)]
struct Wide {
    /// `inp` columns of `width` weights, one after the other.
    columns: Vec<f32>,
    /// The transpose: `width` rows of `inp` weights.
    rows: Vec<f32>,
    bias: Vec<f32>,
}

impl Wide {
    fn new(p: &[f32], l: &LinearAt) -> Wide {
        let columns = p[l.weight..l.weight + l.out * l.inp].to_vec();
        let mut rows = vec![0.0; columns.len()];
        for (i, column) in columns.chunks_exact(l.out).enumerate() {
            for (o, w) in column.iter().enumerate() {
                rows[o * l.inp + i] = *w;
            }
        }
        Wide { columns, rows, bias: p[l.bias..l.bias + l.out].to_vec() }
    }

    /// Number of outputs.
    fn outputs(&self) -> usize {
        self.bias.len()
    }

    /// `y = W x + b`; `nz` is scratch as long as `x`.
    #[inline(always)]
    fn forward<M: MulAdd, const B: usize>(&self, x: &[f32], y: &mut [f32], nz: &mut [u32]) {
        mat_vec::<M, B>(&self.columns, Some(&self.bias), x, y, nz);
    }

    /// `g_x = W^T g_y`, skipping the rows where `g_y` is zero.
    #[inline(always)]
    fn backward<M: MulAdd, const B: usize>(&self, gy: &[f32], gx: &mut [f32], nz: &mut [u32]) {
        mat_vec::<M, B>(&self.rows, None, gy, gx, nz);
    }

    /// `g_x = W^T g_y` where `slope` (of the activation that made the
    /// input) is not zero, 0 elsewhere. The slope itself is applied by the
    /// caller.
    #[inline(always)]
    fn backward_where<M: MulAdd, const B: usize>(
        &self,
        gy: &[f32],
        slope: &[f32],
        gx: &mut [f32],
        nz: &mut [u32],
    ) {
        self.backward::<M, B>(gy, gx, nz);
        for (g, s) in gx.iter_mut().zip(slope) {
            *g = if *s != 0.0 { *g } else { 0.0 };
        }
    }

    /// `g_x = slope * (W^T g_y)`: the gradient at an activation's input
    /// from its output's.
    #[inline(always)]
    fn backward_scaled<M: MulAdd, const B: usize>(
        &self,
        gy: &[f32],
        slope: &[f32],
        gx: &mut [f32],
        nz: &mut [u32],
    ) {
        self.backward_where::<M, B>(gy, slope, gx, nz);
        scale(gx, slope);
    }
}

/// `g <- g * slope` elementwise.
#[inline(always)]
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
    /// Scratch for the indices of a vector's non-zero elements.
    nz: Vec<u32>,
    /// The largest width of a layer (or input).
    width: usize,
    /// The instruction set the kernels run with.
    isa: Isa,
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
            nz: vec![0; width.max(net_inputs(net))],
            width,
            isa: Isa::detect(),
        }
    }

    /// The network's output for `input`, keeping the activations.
    pub fn value(&mut self, input: &[f32]) -> f32 {
        match self.isa {
            #[cfg(target_arch = "x86_64")]
            Isa::V3(simd) => simd.vectorize(
                #[inline(always)]
                || self.forward_pass::<Fused, V3_BLOCK>(input),
            ),
            Isa::Portable => self.forward_pass::<Separate, PORTABLE_BLOCK>(input),
        }
    }

    /// The output and its gradient with respect to a two-dimensional input.
    pub fn value_and_gradient(&mut self, input: [f32; 2]) -> (f32, [f32; 2]) {
        match self.isa {
            #[cfg(target_arch = "x86_64")]
            Isa::V3(simd) => simd.vectorize(
                #[inline(always)]
                || (self.forward_pass::<Fused, V3_BLOCK>(&input), self.reverse_pass::<Fused, V3_BLOCK>()),
            ),
            Isa::Portable => (
                self.forward_pass::<Separate, PORTABLE_BLOCK>(&input),
                self.reverse_pass::<Separate, PORTABLE_BLOCK>(),
            ),
        }
    }

    /// [`FastNet::value`] with multiply-adds `M` and blocks of `B` outputs.
    #[inline(always)]
    fn forward_pass<M: MulAdd, const B: usize>(&mut self, input: &[f32]) -> f32 {
        let mut y = 0.0;
        let nz = &mut self.nz;
        for step in &self.steps {
            let values = &mut self.values;
            match step {
                Step::Linear { layer, from, to } => {
                    let (lo, hi) = values.split_at_mut(to.start);
                    let x = slot(from).map_or(input, |(at, _)| &lo[at.clone()]);
                    layer.forward::<M, B>(x, &mut hi[..to.len()], nz);
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
                    fc1.forward::<M, B>(h, av, nz);
                    activate_vector(*activation, av, sa);
                    fc2.forward::<M, B>(av, sv, nz);
                    for (si, hi) in sv.iter_mut().zip(h) {
                        *si += hi;
                    }
                    activate_vector(*activation, sv, ss);
                }
                Step::Output { weight, bias, from } => y = dot::<M>(weight, &values[from.clone()]) + bias,
            }
        }
        y
    }

    /// Reverse pass through a residual block: `g` holds the gradient at its
    /// output on entry and at its input on return. The input's own
    /// activation slope (when the input is an activation's output) is not
    /// applied here; the gradient it would zero is zeroed.
    #[inline(always)]
    fn residual_back<M: MulAdd, const B: usize>(
        &self,
        step: &Step,
        g: &mut [f32],
        [ga, gh]: [&mut [f32]; 2],
        nz: &mut [u32],
    ) {
        let Step::Residual { fc1, fc2, from, from_activated, a, .. } = step else { return };
        let s = a.end..a.end + g.len();
        let (ga, gh) = (&mut ga[..a.len()], &mut gh[..from.len()]);
        scale(g, &self.slopes[s]);
        fc2.backward_scaled::<M, B>(g, &self.slopes[a.clone()], ga, nz);
        if *from_activated {
            fc1.backward_where::<M, B>(ga, &self.slopes[from.clone()], gh, nz);
        } else {
            fc1.backward::<M, B>(ga, gh, nz);
        }
        for (gi, x) in g.iter_mut().zip(gh.iter()) {
            *gi += x;
        }
    }

    /// The gradient of the output with respect to the two-dimensional
    /// input, after a forward pass.
    #[inline(always)]
    fn reverse_pass<M: MulAdd, const B: usize>(&mut self) -> [f32; 2] {
        let w = self.width;
        let mut scratch = std::mem::take(&mut self.scratch);
        let mut nz = std::mem::take(&mut self.nz);
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
                Step::Residual { .. } => {
                    self.residual_back::<M, B>(step, &mut cur[..n], [&mut *ga, &mut *gh], &mut nz);
                }
                Step::Linear { layer, from, .. } => match slot(from) {
                    None => layer.backward::<M, B>(&cur[..n], &mut gx, &mut nz),
                    Some((at, activated)) => {
                        let gx = &mut other[..at.len()];
                        if activated {
                            layer.backward_where::<M, B>(&cur[..n], &self.slopes[at.clone()], gx, &mut nz);
                        } else {
                            layer.backward::<M, B>(&cur[..n], gx, &mut nz);
                        }
                        n = at.len();
                        std::mem::swap(&mut cur, &mut other);
                    }
                },
            }
        }
        self.scratch = scratch;
        self.nz = nz;
        gx
    }
}

/// The number of inputs of network `net` (of its first layer).
fn net_inputs(net: &NetAt) -> usize {
    match net.layers.first() {
        Some(Layer::Linear(l)) => l.inp,
        Some(Layer::Residual { fc1, .. }) => fc1.inp,
        _ => 0,
    }
}

#[cfg(test)]
mod tests {
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

#[cfg(test)]
mod timing {
    use super::*;
    use crate::dekf::params::Layout;
    use rand::SeedableRng;
    use std::time::Instant;

    /// Median and minimum time (us) of the three networks of one dEKF
    /// step (two values with gradients, one feature value) with `isa`.
    fn time_step(isa: Isa) -> (f64, f64, f32) {
        let layout = Layout::new(6);
        let p = layout.init(&mut rand::rngs::StdRng::seed_from_u64(3));
        let mut nets = [&layout.motion, &layout.measurement, &layout.feature].map(|n| FastNet::new(&p, n));
        for n in &mut nets {
            n.isa = isa;
        }
        let mut runs = Vec::new();
        let mut sum = 0.0;
        for r in 0..200 {
            let started = Instant::now();
            for k in 0..200 {
                let x = [(r * 200 + k) as f32 * 1e-3 % 3.0 - 1.5, (k as f32 * 0.37).sin()];
                let (a, g) = nets[0].value_and_gradient(x);
                let (b, h) = nets[1].value_and_gradient([x[1], x[0]]);
                let z = [x[0], x[1], a, b, g[0], h[1]];
                sum += nets[2].value(&z);
            }
            runs.push(started.elapsed().as_secs_f64() / 200.0 * 1e6);
        }
        runs.sort_by(f64::total_cmp);
        (runs[runs.len() / 2], runs[0], sum)
    }

    /// `cargo test --release -p slidetrack-estimators --lib time_the_networks -- --ignored --nocapture`
    #[test]
    #[ignore = "timing aid"]
    fn time_the_networks_of_one_step() {
        for _ in 0..3 {
            for (name, isa) in [("portable", Isa::Portable), ("detected", Isa::detect())] {
                let (median, min, sum) = time_step(isa);
                println!(
                    "{name:>9} ({isa:?}): median {median:.2} us, min {min:.2} us per step (checksum {sum})"
                );
            }
        }
    }
}
