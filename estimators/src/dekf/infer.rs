//! Fast evaluation of one sample (the online path): the second executor of
//! a network's list of layers ([`NetAt::layers`], the first being the
//! batched pass of [`super::mlp`]). The list is compiled once, when the
//! network is built, into steps that read and write slots of one buffer;
//! every buffer is allocated then, none in a step.
//!
//! A network's value is one forward pass. Its gradient with respect to a
//! two-dimensional input (the Jacobians `F` and `H` of the dEKF) is carried
//! forward with the value, as the batched pass does with its tangent
//! columns: every slot holds a value and its two tangents (its derivatives
//! with respect to the two inputs), and each linear layer computes the
//! three products `W x + b`, `W t_0`, `W t_1` in one sweep over its
//! weights (the parameters' own column-by-column layout), so each weight is
//! read once per step and no transposed copy is kept. The products are the
//! register-blocked kernels of `kernels`, which skip the inputs that are
//! zero (the ones a ReLU zeroed, whose tangents it zeroed too). The value
//! is the same sum as the value-only pass, term for term; the gradient is
//! the reverse-mode one up to rounding. The activation is dispatched once
//! per layer, outside the inner loops.
//!
//! A whole pass runs inside one dispatch to the instruction set found when
//! the network was built (`kernels::Isa`): AVX2 with fused multiply-adds
//! where the CPU has them, the build's baseline otherwise. The two differ
//! only in rounding (the fused one rounds once per multiply-add). Timing
//! aid: `cargo test --release -p slidetrack-estimators --lib
//! time_the_networks -- --ignored --nocapture` (see `docs/dekf.md`).

use std::ops::Range;

use super::mlp::activate_vector;
use super::params::{Activation, Layer, LinearAt, NetAt};

mod kernels;

#[cfg(target_arch = "x86_64")]
use kernels::{Fused, V3_BLOCK, V3_TANGENT_BLOCK};
use kernels::{
    Isa, MulAdd, PORTABLE_BLOCK, PORTABLE_TANGENT_BLOCK, Separate, dot, mat_vec, mat_vec_tangents,
};

/// Floats a cache line holds (64 bytes).
const LINE_FLOATS: usize = 16;

/// A copy of some floats that starts on a 64-byte boundary (a cache line),
/// so that a column of 64 weights is four lines and no 32-byte load spans
/// two of them (the allocator aligns a `Vec<f32>` to 16 bytes only). The
/// floats sit at `start` in a buffer up to 15 floats longer; a clone aligns
/// its own buffer.
#[derive(Debug)]
struct LineAligned {
    buffer: Vec<f32>,
    start: usize,
    len: usize,
}

impl LineAligned {
    fn new(floats: &[f32]) -> LineAligned {
        let mut buffer = vec![0.0f32; floats.len() + LINE_FLOATS - 1];
        // The buffer is never grown, so its address stays the same.
        let misaligned = buffer.as_ptr().addr() % (4 * LINE_FLOATS) / 4;
        let start = (LINE_FLOATS - misaligned) % LINE_FLOATS;
        buffer[start..start + floats.len()].copy_from_slice(floats);
        LineAligned { buffer, start, len: floats.len() }
    }

    fn get(&self) -> &[f32] {
        &self.buffer[self.start..self.start + self.len]
    }
}

impl Clone for LineAligned {
    fn clone(&self) -> LineAligned {
        LineAligned::new(self.get())
    }
}

/// A linear layer with `width` outputs: its weights column by column (one
/// column per input), as the parameters store them, from a cache line's
/// start.
#[derive(Clone, Debug)]
struct Wide {
    /// `inp` columns of `width` weights, one after the other.
    columns: LineAligned,
    bias: Vec<f32>,
}

impl Wide {
    fn new(p: &[f32], l: &LinearAt) -> Wide {
        Wide {
            columns: LineAligned::new(&p[l.weight..l.weight + l.out * l.inp]),
            bias: p[l.bias..l.bias + l.out].to_vec(),
        }
    }

    /// Number of outputs.
    fn outputs(&self) -> usize {
        self.bias.len()
    }

    /// `y = W x + b`; `nz` is scratch as long as `x`.
    #[inline(always)]
    fn forward<M: MulAdd, const B: usize>(&self, isa: M, x: &[f32], y: &mut [f32], nz: &mut [u32]) {
        mat_vec::<M, B>(isa, self.columns.get(), Some(&self.bias), x, y, nz);
    }

    /// `y = W x + b` and the tangents `W t`, for `x` and its two tangents
    /// in `[x, t_0, t_1]`; `nz` is scratch as long as `x`.
    #[inline(always)]
    fn forward_tangents<M: MulAdd, const B: usize>(
        &self,
        isa: M,
        x: [&[f32]; 3],
        y: [&mut [f32]; 3],
        nz: &mut [u32],
    ) {
        mat_vec_tangents::<M, B>(isa, self.columns.get(), &self.bias, x, y, nz);
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
    Residual { fc1: Wide, fc2: Wide, activation: Activation, from: Range<usize>, a: Range<usize> },
    /// The last layer, with one output: `weight . h + bias`.
    Output { weight: Vec<f32>, bias: f32, from: Range<usize> },
}

/// Values and their two tangents by slot, the three at the same places of
/// their own buffers (a borrowed view, split like a slice).
struct Lanes<'a>([&'a mut [f32]; 3]);

impl<'a> Lanes<'a> {
    /// The slots before `at` and from `at` on.
    fn split_at(self, at: usize) -> (Lanes<'a>, Lanes<'a>) {
        let [v, t0, t1] = self.0.map(|l| l.split_at_mut(at));
        (Lanes([v.0, t0.0, t1.0]), Lanes([v.1, t0.1, t1.1]))
    }

    /// Value and tangents of `r`.
    fn get(&self, r: &Range<usize>) -> [&[f32]; 3] {
        [&self.0[0][r.clone()], &self.0[1][r.clone()], &self.0[2][r.clone()]]
    }

    /// Value and tangents of `r`, writable.
    fn get_mut(&mut self, r: &Range<usize>) -> [&mut [f32]; 3] {
        let [v, t0, t1] = &mut self.0;
        [&mut v[r.clone()], &mut t0[r.clone()], &mut t1[r.clone()]]
    }
}

/// Applies `activation` to the values of `v` in place, keeping its slopes
/// in `slopes`, and scales the tangents by them (the chain rule).
#[inline(always)]
fn activate_with_tangents(activation: Activation, [v, t0, t1]: [&mut [f32]; 3], slopes: &mut [f32]) {
    activate_vector(activation, v, slopes);
    scale(t0, slopes);
    scale(t1, slopes);
}

/// One network with one output and scratch space for a forward pass, with
/// or without tangents: the steps of its layers, and buffers with a slot
/// for every layer's output (an activation works in place).
#[derive(Clone, Debug)]
pub struct FastNet {
    steps: Vec<Step>,
    /// Activation values by slot.
    values: Vec<f32>,
    /// The two tangents of the values, by slot (as `values`).
    tangents: [Vec<f32>; 2],
    /// The activation's slope at every value of an activated slot.
    slopes: Vec<f32>,
    /// Scratch for the indices of a vector's non-zero elements.
    nz: Vec<u32>,
    /// The instruction set the kernels run with.
    isa: Isa,
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
                Source::Slot { at } => at.clone(),
                Source::Input => unreachable!("layer {i} reads the input: only a linear layer may"),
            };
            match layer {
                Layer::Linear(l) if i == last => {
                    assert_eq!(l.out, 1, "the fast path is for networks with one output");
                    // [1, inp] column-major: one weight per input, contiguous.
                    steps.push(Step::Output {
                        weight: p[l.weight..l.weight + l.inp].to_vec(),
                        bias: p[l.bias],
                        from: slot_of(&current),
                    });
                }
                Layer::Linear(l) => {
                    let to = new_slot(l.out);
                    let from = std::mem::replace(&mut current, Source::Slot { at: to.clone() });
                    steps.push(Step::Linear { layer: Wide::new(p, l), from, to });
                }
                Layer::Activation(activation) => {
                    steps.push(Step::Activation { activation: *activation, at: slot_of(&current) });
                }
                Layer::Residual { fc1, fc2, activation } => {
                    let from = slot_of(&current);
                    let a = new_slot(fc1.out);
                    current = Source::Slot { at: new_slot(fc2.out) };
                    let (fc1, fc2) = (Wide::new(p, fc1), Wide::new(p, fc2));
                    steps.push(Step::Residual { fc1, fc2, activation: *activation, from, a });
                }
            }
        }
        FastNet {
            steps,
            values: vec![0.0; len],
            tangents: [vec![0.0; len], vec![0.0; len]],
            slopes: vec![0.0; len],
            nz: vec![0; width.max(net_inputs(net))],
            isa: Isa::detect(),
        }
    }

    /// The network's output for `input`.
    ///
    /// The closures given to `vectorize` move `self` out of their capture
    /// (`let this = this`), which makes them `FnOnce` closures whose body is
    /// their `call_once`. A closure that only borrows is called through a
    /// compiler-made `FnOnce::call_once` shim that is not `inline(always)`:
    /// in the dev profile (opt-level 1, many codegen units) the shim stayed
    /// out of the AVX2+FMA function, so every fused multiply-add became a
    /// library call (`fmaf`), half of a debug build's training time.
    pub fn value(&mut self, input: &[f32]) -> f32 {
        match self.isa {
            #[cfg(target_arch = "x86_64")]
            Isa::V3(simd) => {
                let this = self;
                simd.vectorize(
                    #[inline(always)]
                    move || {
                        let this = this;
                        this.forward_pass::<_, V3_BLOCK>(Fused(simd), input)
                    },
                )
            }
            Isa::Portable => self.forward_pass::<_, PORTABLE_BLOCK>(Separate, input),
        }
    }

    /// The output and its gradient with respect to a two-dimensional input.
    pub fn value_and_gradient(&mut self, input: [f32; 2]) -> (f32, [f32; 2]) {
        match self.isa {
            #[cfg(target_arch = "x86_64")]
            Isa::V3(simd) => {
                let this = self;
                simd.vectorize(
                    #[inline(always)]
                    move || {
                        let this = this;
                        this.tangent_pass::<_, V3_TANGENT_BLOCK>(Fused(simd), input)
                    },
                )
            }
            Isa::Portable => self.tangent_pass::<_, PORTABLE_TANGENT_BLOCK>(Separate, input),
        }
    }

    /// [`FastNet::value`] with multiply-adds `M` and blocks of `B` outputs.
    #[inline(always)]
    fn forward_pass<M: MulAdd, const B: usize>(&mut self, isa: M, input: &[f32]) -> f32 {
        let mut y = 0.0;
        let nz = &mut self.nz;
        for step in &self.steps {
            let values = &mut self.values;
            match step {
                Step::Linear { layer, from, to } => {
                    let (lo, hi) = values.split_at_mut(to.start);
                    let x = match from {
                        Source::Input => input,
                        Source::Slot { at } => &lo[at.clone()],
                    };
                    layer.forward::<M, B>(isa, x, &mut hi[..to.len()], nz);
                }
                Step::Activation { activation, at } => {
                    activate_vector(*activation, &mut values[at.clone()], &mut self.slopes[at.clone()]);
                }
                Step::Residual { fc1, fc2, activation, from, a } => {
                    // a = act(fc1 h), s = act(fc2 a + h).
                    let (lo, hi) = values.split_at_mut(a.start);
                    let h = &lo[from.clone()];
                    let (av, sv) = hi.split_at_mut(a.len());
                    let sv = &mut sv[..fc2.outputs()];
                    let slopes = &mut self.slopes[a.start..a.end + sv.len()];
                    let (sa, ss) = slopes.split_at_mut(a.len());
                    fc1.forward::<M, B>(isa, h, av, nz);
                    activate_vector(*activation, av, sa);
                    fc2.forward::<M, B>(isa, av, sv, nz);
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

    /// [`FastNet::value_and_gradient`] with multiply-adds `M` and blocks
    /// of `T` outputs: the forward pass carrying the derivatives of every
    /// value with respect to the two inputs.
    #[inline(always)]
    fn tangent_pass<M: MulAdd, const T: usize>(&mut self, isa: M, input: [f32; 2]) -> (f32, [f32; 2]) {
        // The input's tangents: the identity.
        let input_tangents = [[1.0f32, 0.0], [0.0, 1.0]];
        let mut out = (0.0, [0.0; 2]);
        let nz = &mut self.nz;
        let [t0, t1] = &mut self.tangents;
        for step in &self.steps {
            let lanes = Lanes([&mut self.values[..], &mut t0[..], &mut t1[..]]);
            match step {
                Step::Linear { layer, from, to } => {
                    let (lo, mut hi) = lanes.split_at(to.start);
                    let x = match from {
                        Source::Input => [&input[..], &input_tangents[0][..], &input_tangents[1][..]],
                        Source::Slot { at } => lo.get(at),
                    };
                    layer.forward_tangents::<M, T>(isa, x, hi.get_mut(&(0..to.len())), nz);
                }
                Step::Activation { activation, at } => {
                    let mut lanes = lanes;
                    activate_with_tangents(*activation, lanes.get_mut(at), &mut self.slopes[at.clone()]);
                }
                Step::Residual { fc1, fc2, activation, from, a } => {
                    // a = act(fc1 h), s = act(fc2 a + h), with tangents.
                    let (lo, hi) = lanes.split_at(a.start);
                    let h = lo.get(from);
                    let (mut la, mut ls) = hi.split_at(a.len());
                    let s = 0..fc2.outputs();
                    let slopes = &mut self.slopes[a.start..a.end + s.len()];
                    let (sa, ss) = slopes.split_at_mut(a.len());
                    fc1.forward_tangents::<M, T>(isa, h, la.get_mut(&(0..a.len())), nz);
                    activate_with_tangents(*activation, la.get_mut(&(0..a.len())), sa);
                    fc2.forward_tangents::<M, T>(isa, la.get(&(0..a.len())), ls.get_mut(&s), nz);
                    let mut sl = ls.get_mut(&s);
                    for (lane, h) in sl.iter_mut().zip(h) {
                        for (si, hi) in lane.iter_mut().zip(h.iter()) {
                            *si += hi;
                        }
                    }
                    activate_with_tangents(*activation, sl, ss);
                }
                Step::Output { weight, bias, from } => {
                    let [h, g0, g1] = lanes.get(from);
                    out = (dot::<M>(weight, h) + bias, [dot::<M>(weight, g0), dot::<M>(weight, g1)]);
                }
            }
        }
        out
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

    /// The weights' copy starts on a 64-byte boundary and holds the floats
    /// given, for every length and in a clone (whose buffer is a new
    /// allocation); catches an offset computed in bytes instead of floats,
    /// or a clone that copies the old offset into a differently aligned
    /// buffer.
    #[test]
    fn line_aligned_weights_start_on_a_cache_line_with_the_same_floats() {
        for len in [0, 1, 15, 16, 17, 64 * 64] {
            let floats: Vec<f32> = (0..len).map(|k| k as f32 * 0.5 - 3.0).collect();
            let a = LineAligned::new(&floats);
            let clones: Vec<LineAligned> = (0..8).map(|_| a.clone()).collect();
            for x in std::iter::once(&a).chain(&clones) {
                assert_eq!(x.get(), &floats[..], "length {len}");
                assert_eq!(x.get().as_ptr().addr() % 64, 0, "length {len}");
            }
        }
    }

    /// One network reused over a walk of inputs whose ReLU patterns change
    /// from step to step, value passes and passes with tangents
    /// interleaved (they share the scratch of non-zero lists and slopes):
    /// every result is the bits of a network built for that input alone,
    /// and the batched forward's within rounding. Catches a list of
    /// non-zero inputs (or slopes) kept from an earlier step or another
    /// layer, or a list built from the value only where a tangent is not
    /// zero (tanh, GELU).
    #[test]
    fn a_reused_network_equals_a_fresh_one_whatever_the_sparsity_before() {
        for arch in crate::dekf::mlp::tests::architectures() {
            let layout = Layout::with_architecture(6, &arch);
            let p = layout.init(&mut rand::rngs::StdRng::seed_from_u64(5));
            let (mut motion, mut feature) =
                (FastNet::new(&p, &layout.motion), FastNet::new(&p, &layout.feature));
            let mut patterns = std::collections::BTreeSet::new();
            for k in 0..40 {
                let t = k as f32;
                // Large and small, both signs, and exact zeros now and then.
                let x = [if k % 7 == 3 { 0.0 } else { 4.0 * (0.9 * t).sin() }, 3.0 * (0.37 * t).cos() - 1.0];
                let z: Vec<f32> = (0..6)
                    .map(|c| if (k + c) % 5 == 0 { 0.0 } else { (t * 0.5 + c as f32).sin() * 3.0 })
                    .collect();
                let got = motion.value_and_gradient(x);
                patterns.insert(motion.slopes.iter().map(|s| *s > 0.0).collect::<Vec<_>>());
                let got_value = feature.value(&z);
                assert_eq!(got, FastNet::new(&p, &layout.motion).value_and_gradient(x), "{arch:?} step {k}");
                assert_eq!(got_value, FastNet::new(&p, &layout.feature).value(&z), "{arch:?} step {k}");
                let mut m = DMatrix::<f32>::zeros(2, 3);
                m.column_mut(0).copy_from_slice(&x);
                m[(0, 1)] = 1.0;
                m[(1, 2)] = 1.0;
                let (y, _) = forward(&p, &layout.motion, m, 3, false);
                for (c, f) in [got.0, got.1[0], got.1[1]].into_iter().enumerate() {
                    let r = y[(0, c)];
                    assert!(
                        (f - r).abs() < 1e-5 * (1.0 + r.abs()),
                        "{arch:?} step {k} column {c}: {f} vs {r}"
                    );
                }
                let (y3, _) = forward(&p, &layout.feature, DMatrix::from_column_slice(6, 1, &z), 1, false);
                let r = y3[(0, 0)];
                assert!(
                    (got_value - r).abs() < 1e-5 * (1.0 + r.abs()),
                    "{arch:?} step {k}: {got_value} vs {r}"
                );
            }
            if arch.activation == Activation::Relu {
                assert!(patterns.len() >= 10, "{arch:?}: only {} ReLU patterns in the walk", patterns.len());
            }
        }
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
