//! The dEKF's parameters: one flat `f32` vector with a named layout in
//! PyTorch `nn.Module` style (`motion.encoder.linear.weight`, ...). Weights
//! are `[out, in]` matrices stored column-major here (nalgebra's order); the
//! model file holds them row-major, as PyTorch does.

use rand::{Rng, RngExt};
use serde::{Deserialize, Serialize};

use super::state::StateKind;

/// Width of every hidden layer of the thesis's networks (Sec. 6.1.6).
pub const HIDDEN: usize = 64;

/// Residual blocks of the `shared` part of the thesis's networks (Sec. 6.1.6).
pub const THESIS_BLOCKS: usize = 3;

/// Largest hidden width a model may have (a guard against absurd files).
pub const MAX_WIDTH: usize = 4096;

/// Largest number of residual blocks of `shared` a model may have.
pub const MAX_BLOCKS: usize = 64;

/// The nonlinearity of every hidden layer.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Activation {
    /// `max(x, 0)` (the thesis's). Piecewise linear: its second derivative
    /// is zero wherever it is defined, so the networks' Jacobians are
    /// piecewise constant.
    #[default]
    Relu,
    /// `tanh(x)`: smooth, `tanh' = 1 - tanh^2`, `tanh'' = -2 tanh tanh'`.
    Tanh,
    /// GELU in its tanh approximation, `0.5 x (1 + tanh(sqrt(2/pi) (x +
    /// 0.044715 x^3)))` (PyTorch's `nn.GELU(approximate="tanh")`): smooth.
    Gelu,
}

impl Activation {
    /// Every activation, in the order of the documentation.
    pub const ALL: [Activation; 3] = [Activation::Relu, Activation::Tanh, Activation::Gelu];

    /// `relu`, `tanh` or `gelu` (the name in the model file).
    pub fn name(self) -> &'static str {
        match self {
            Activation::Relu => "relu",
            Activation::Tanh => "tanh",
            Activation::Gelu => "gelu",
        }
    }

    /// False for an activation whose second derivative vanishes (ReLU):
    /// then the Jacobian of a network does not depend on its input (between
    /// kinks) and the second-order terms of the backward pass are zero.
    pub fn has_curvature(self) -> bool {
        !matches!(self, Activation::Relu)
    }
}

/// The shape of the three networks: hidden width, residual blocks of
/// `shared` and the activation (Sec. 6.1.6 has 64, 3 and ReLU; the encoder
/// always has one residual block). Recorded in the model file's metadata
/// (`docs/model-format.md`); a file without it has the thesis's.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Architecture {
    /// Width of every hidden layer.
    pub width: usize,
    /// Residual blocks after `shared.linear` (`shared.residual.0..`).
    pub residual_blocks: usize,
    /// The nonlinearity of every hidden layer.
    pub activation: Activation,
}

impl Default for Architecture {
    /// The thesis's: width 64, 3 shared residual blocks, ReLU.
    fn default() -> Self {
        Architecture { width: HIDDEN, residual_blocks: THESIS_BLOCKS, activation: Activation::Relu }
    }
}

impl Architecture {
    /// `None` when the architecture is usable, else what is wrong with it.
    pub fn problem(&self) -> Option<String> {
        if self.width == 0 || self.width > MAX_WIDTH {
            return Some(format!("width {} is not in 1..={MAX_WIDTH}", self.width));
        }
        if self.residual_blocks > MAX_BLOCKS {
            return Some(format!("{} residual blocks, at most {MAX_BLOCKS}", self.residual_blocks));
        }
        None
    }
}

/// One named tensor of the layout.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ParamEntry {
    /// PyTorch-style name.
    pub name: String,
    /// Shape, PyTorch order (`[out, in]` for a weight).
    pub shape: Vec<usize>,
    /// Offset into the flat vector.
    pub offset: usize,
    /// Updated by training (the feature normalisation is not).
    pub trainable: bool,
}

impl ParamEntry {
    /// Number of elements.
    pub fn len(&self) -> usize {
        self.shape.iter().product()
    }

    /// True for a tensor with no elements.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The range of this tensor in the flat vector.
    pub fn range(&self) -> std::ops::Range<usize> {
        self.offset..self.offset + self.len()
    }
}

/// A linear layer's place in the flat vector.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LinearAt {
    /// Offset of the `[out, in]` weight, stored column-major.
    pub weight: usize,
    /// Offset of the `[out]` bias.
    pub bias: usize,
    /// Output size.
    pub out: usize,
    /// Input size.
    pub inp: usize,
}

/// One layer of a network, in evaluation order. A network is an ordered
/// list of them ([`NetAt::layers`]), written once, in [`Layout::for_state`];
/// the batched pass of training ([`super::mlp`]) and the fast online pass
/// (`infer`) are two executors of that list.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Layer {
    /// `y = W x + b` (`torch.nn.Linear`).
    Linear(LinearAt),
    /// `y = act(x)`, elementwise.
    Activation(Activation),
    /// A residual block, `y = act(fc2(act(fc1(x))) + x)` (`fc1` and `fc2`
    /// square, the width of `x`).
    Residual {
        /// The first linear layer.
        fc1: LinearAt,
        /// The second linear layer, whose output the input is added to.
        fc2: LinearAt,
        /// The nonlinearity after each of them.
        activation: Activation,
    },
}

/// One network: its layers in evaluation order (see [`Layout::for_state`]
/// for the list of the thesis's networks).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct NetAt {
    /// The layers, first to last; the last is linear.
    pub layers: Vec<Layer>,
}

impl NetAt {
    /// Every linear layer in evaluation order, those of the residual blocks
    /// included (`fc1` before `fc2`): the order of the model file's tensors.
    pub fn linears(&self) -> impl Iterator<Item = &LinearAt> {
        self.layers
            .iter()
            .flat_map(|layer| match layer {
                Layer::Linear(l) => [Some(l), None],
                Layer::Activation(_) => [None, None],
                Layer::Residual { fc1, fc2, .. } => [Some(fc1), Some(fc2)],
            })
            .flatten()
    }

    /// The output layer (the last layer, `[outputs, width]`).
    pub fn out(&self) -> &LinearAt {
        match self.layers.last() {
            Some(Layer::Linear(l)) => l,
            _ => unreachable!("a network ends with a linear layer"),
        }
    }

    /// Size of the network's input.
    pub fn inputs(&self) -> usize {
        self.linears().next().map_or(0, |l| l.inp)
    }

    /// Size of the network's output.
    pub fn outputs(&self) -> usize {
        self.out().out
    }
}

/// Where every tensor of a model with `channels` tactile inputs lives.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Layout {
    /// Every tensor, in file order.
    pub entries: Vec<ParamEntry>,
    /// NN1, the motion network (input: the state).
    pub motion: NetAt,
    /// NN2, the measurement network (input: the state).
    pub measurement: NetAt,
    /// NN3, the feature network (input: the normalised tactile measurement).
    pub feature: NetAt,
    /// `process_noise.cholesky`, `[2 dofs, 2 dofs]` (lower triangle used).
    pub process_noise: usize,
    /// `measurement_noise.cholesky`, `[dofs, dofs]` (lower triangle used).
    pub measurement_noise: usize,
    /// `feature.input_mean`, `[channels]`.
    pub input_mean: usize,
    /// `feature.input_std`, `[channels]`.
    pub input_std: usize,
    /// Tactile inputs of NN3.
    pub channels: usize,
    /// Width, depth and activation of the networks.
    pub architecture: Architecture,
    /// The state the networks read and predict.
    pub state: StateKind,
    /// Length of the flat vector.
    pub len: usize,
}

struct Builder {
    entries: Vec<ParamEntry>,
    len: usize,
}

impl Builder {
    fn add(&mut self, name: String, shape: Vec<usize>, trainable: bool) -> usize {
        let offset = self.len;
        let entry = ParamEntry { name, shape, offset, trainable };
        self.len += entry.len();
        self.entries.push(entry);
        offset
    }

    fn linear(&mut self, prefix: &str, out: usize, inp: usize) -> LinearAt {
        let weight = self.add(format!("{prefix}.weight"), vec![out, inp], true);
        let bias = self.add(format!("{prefix}.bias"), vec![out], true);
        LinearAt { weight, bias, out, inp }
    }

    /// Residual block `prefix` (`fc1`, `fc2`) of width `h`.
    fn residual(&mut self, prefix: &str, h: usize, activation: Activation) -> Layer {
        let fc1 = self.linear(&format!("{prefix}.fc1"), h, h);
        let fc2 = self.linear(&format!("{prefix}.fc2"), h, h);
        Layer::Residual { fc1, fc2, activation }
    }

    /// The network of Sec. 6.1.6, the one description of it: with `act`
    /// the activation, `W` the width and `B` the residual blocks of `shared`,
    ///
    /// ```text
    /// encoder.linear    Linear(inp, W)
    ///                   act
    /// encoder.residual  Residual(W)
    /// shared.linear     Linear(W, W)          (no activation)
    /// shared.residual.k Residual(W)           k = 0..B
    /// shared.out        Linear(W, out)
    /// ```
    ///
    /// Tensors are added in this order (the model file's and the flat
    /// vector's), named `<name>.<layer>.weight` and `.bias`.
    fn net(&mut self, name: &str, inp: usize, out: usize, arch: &Architecture) -> NetAt {
        let (h, act) = (arch.width, arch.activation);
        let mut layers = vec![
            Layer::Linear(self.linear(&format!("{name}.encoder.linear"), h, inp)),
            Layer::Activation(act),
            self.residual(&format!("{name}.encoder.residual"), h, act),
            Layer::Linear(self.linear(&format!("{name}.shared.linear"), h, h)),
        ];
        for k in 0..arch.residual_blocks {
            layers.push(self.residual(&format!("{name}.shared.residual.{k}"), h, act));
        }
        layers.push(Layer::Linear(self.linear(&format!("{name}.shared.out"), out, h)));
        NetAt { layers }
    }
}

impl Layout {
    /// The layout of a model with the thesis's networks whose feature
    /// network reads `channels` inputs.
    pub fn new(channels: usize) -> Layout {
        Layout::with_architecture(channels, &Architecture::default())
    }

    /// The layout of a sliding model with networks of `arch` whose feature
    /// network reads `channels` inputs.
    pub fn with_architecture(channels: usize, arch: &Architecture) -> Layout {
        Layout::for_state(StateKind::Sliding, channels, arch)
    }

    /// The layout of a model of `state` with networks of `arch` whose
    /// feature network reads `channels` inputs: NN1 and NN2 read the state
    /// (`2 dofs`) and output `dofs` values (accelerations, expected
    /// features), NN3 maps the channels to `dofs` features. A sliding
    /// model's tensors are the thesis's, named and shaped as before planar
    /// models existed.
    pub fn for_state(state: StateKind, channels: usize, arch: &Architecture) -> Layout {
        let (n, m) = (state.dim(), state.dofs());
        let mut b = Builder { entries: Vec::new(), len: 0 };
        let motion = b.net("motion", n, m, arch);
        let measurement = b.net("measurement", n, m, arch);
        let feature = b.net("feature", channels, m, arch);
        let input_mean = b.add("feature.input_mean".into(), vec![channels], false);
        let input_std = b.add("feature.input_std".into(), vec![channels], false);
        let process_noise = b.add("process_noise.cholesky".into(), vec![n, n], true);
        let measurement_noise = b.add("measurement_noise.cholesky".into(), vec![m, m], true);
        Layout {
            entries: b.entries,
            motion,
            measurement,
            feature,
            process_noise,
            measurement_noise,
            input_mean,
            input_std,
            channels,
            architecture: *arch,
            state,
            len: b.len,
        }
    }

    /// The entry named `name`.
    pub fn entry(&self, name: &str) -> Option<&ParamEntry> {
        self.entries.iter().find(|e| e.name == name)
    }

    /// Fresh parameters: PyTorch's default initialisation of linear layers
    /// (weights and biases uniform in `±1/sqrt(in)`); `L_Q = diag(0.1, 0.3)`
    /// (0.1 for every position, 0.3 for every rate), `L_R = I`; input
    /// normalisation mean 0, std 1.
    pub fn init(&self, rng: &mut impl Rng) -> Vec<f32> {
        let mut p = vec![0.0f32; self.len];
        for net in [&self.motion, &self.measurement, &self.feature] {
            for l in net.linears() {
                let bound = 1.0 / (l.inp as f32).sqrt();
                for v in &mut p[l.weight..l.weight + l.out * l.inp] {
                    *v = rng.random_range(-bound..bound);
                }
                for v in &mut p[l.bias..l.bias + l.out] {
                    *v = rng.random_range(-bound..bound);
                }
            }
        }
        let (n, m) = (self.state.dim(), self.state.dofs());
        for i in 0..n {
            p[self.process_noise + i * n + i] = if i < m { 0.1 } else { 0.3 };
        }
        for i in 0..m {
            p[self.measurement_noise + i * m + i] = 1.0;
        }
        for v in &mut p[self.input_std..self.input_std + self.channels] {
            *v = 1.0;
        }
        p
    }

    /// A mask of the trainable elements of the flat vector (the upper
    /// triangles of `process_noise.cholesky` and `measurement_noise.cholesky`
    /// are not trained: `L_Q` and `L_R` are lower-triangular).
    pub fn trainable_mask(&self) -> Vec<bool> {
        let mut mask = vec![false; self.len];
        for e in &self.entries {
            if e.trainable {
                mask[e.range()].iter_mut().for_each(|m| *m = true);
            }
        }
        for i in self.upper_triangles() {
            mask[i] = false;
        }
        mask
    }

    /// The elements above the diagonal of the two Cholesky factors (stored
    /// row-major, `[row, column]`), which are zero.
    pub fn upper_triangles(&self) -> Vec<usize> {
        let (n, m) = (self.state.dim(), self.state.dofs());
        let upper =
            |offset: usize, k: usize| (0..k).flat_map(move |r| (r + 1..k).map(move |c| offset + r * k + c));
        upper(self.process_noise, n).chain(upper(self.measurement_noise, m)).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_follow_the_documented_pytorch_layout() {
        let l = Layout::new(6);
        let names: Vec<&str> = l.entries.iter().map(|e| e.name.as_str()).collect();
        assert_eq!(names[0], "motion.encoder.linear.weight");
        assert!(names.contains(&"measurement.shared.residual.2.fc2.bias"));
        assert!(names.contains(&"feature.shared.out.weight"));
        assert_eq!(l.entry("feature.encoder.linear.weight").unwrap().shape, vec![64, 6]);
        assert_eq!(l.entry("motion.shared.out.weight").unwrap().shape, vec![1, 64]);
        assert_eq!(l.entry("process_noise.cholesky").unwrap().shape, vec![2, 2]);
        // 3 networks x 11 layers x (weight + bias) + 4 others.
        assert_eq!(l.entries.len(), 3 * 22 + 4);
        let total: usize = l.entries.iter().map(ParamEntry::len).sum();
        assert_eq!(total, l.len);
        assert_eq!(l.architecture, Architecture::default());
    }

    #[test]
    fn the_architecture_sets_the_widths_and_the_number_of_blocks() {
        let arch = Architecture { width: 12, residual_blocks: 1, activation: Activation::Tanh };
        let l = Layout::with_architecture(5, &arch);
        // 3 networks x (5 + 2 x 1) layers x (weight + bias) + 4 others.
        assert_eq!(l.entries.len(), 3 * 14 + 4);
        assert_eq!(l.entry("feature.encoder.linear.weight").unwrap().shape, vec![12, 5]);
        assert_eq!(l.entry("motion.shared.residual.0.fc2.weight").unwrap().shape, vec![12, 12]);
        assert!(l.entry("motion.shared.residual.1.fc1.weight").is_none());
        assert_eq!(l.entry("measurement.shared.out.weight").unwrap().shape, vec![1, 12]);
        for net in [&l.motion, &l.measurement, &l.feature] {
            // Linear, act, the encoder's block, shared.linear, one block, out.
            assert_eq!(net.layers.len(), 6);
            assert_eq!(net.layers[1], Layer::Activation(Activation::Tanh));
            assert!(net.layers.iter().all(|layer| match layer {
                Layer::Residual { fc1, fc2, activation } =>
                    *activation == Activation::Tanh
                        && (fc1.out, fc1.inp, fc2.out, fc2.inp) == (12, 12, 12, 12),
                _ => true,
            }));
            assert_eq!(net.linears().count(), 7);
            assert_eq!(net.outputs(), 1);
        }
        assert_eq!((l.motion.inputs(), l.feature.inputs()), (2, 5));
        // The linear layers come in the order of the file's tensors.
        let weights: Vec<&str> = l
            .motion
            .linears()
            .map(|at| l.entries.iter().find(|e| e.offset == at.weight).unwrap().name.as_str())
            .collect();
        assert_eq!(
            weights,
            [
                "motion.encoder.linear.weight",
                "motion.encoder.residual.fc1.weight",
                "motion.encoder.residual.fc2.weight",
                "motion.shared.linear.weight",
                "motion.shared.residual.0.fc1.weight",
                "motion.shared.residual.0.fc2.weight",
                "motion.shared.out.weight",
            ]
        );
        let none = Layout::with_architecture(2, &Architecture { residual_blocks: 0, ..arch });
        assert_eq!(none.motion.layers.len(), 5);
        assert_eq!(none.motion.linears().count(), 5);
    }
}
