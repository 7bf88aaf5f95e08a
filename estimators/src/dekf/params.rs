//! The dEKF's parameters: one flat `f32` vector with a named layout in
//! PyTorch `nn.Module` style (`motion.encoder.linear.weight`, ...). Weights
//! are `[out, in]` matrices stored column-major here (nalgebra's order); the
//! model file holds them row-major, as PyTorch does.

use rand::{Rng, RngExt};

/// Width of every hidden layer (Sec. 6.1.6).
pub const HIDDEN: usize = 64;

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

/// The eleven linear layers of one network, in evaluation order:
/// `encoder.linear`, `encoder.residual.fc1/fc2`, `shared.linear`,
/// `shared.residual.{0,1,2}.fc1/fc2`, `shared.out`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct NetAt {
    /// The layers.
    pub layers: [LinearAt; 11],
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
    /// `process_noise.cholesky`, `[2, 2]` (lower triangle used).
    pub process_noise: usize,
    /// `measurement_noise.cholesky`, `[1, 1]`.
    pub measurement_noise: usize,
    /// `feature.input_mean`, `[channels]`.
    pub input_mean: usize,
    /// `feature.input_std`, `[channels]`.
    pub input_std: usize,
    /// Tactile inputs of NN3.
    pub channels: usize,
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

    fn net(&mut self, name: &str, inp: usize) -> NetAt {
        let h = HIDDEN;
        let layers = [
            self.linear(&format!("{name}.encoder.linear"), h, inp),
            self.linear(&format!("{name}.encoder.residual.fc1"), h, h),
            self.linear(&format!("{name}.encoder.residual.fc2"), h, h),
            self.linear(&format!("{name}.shared.linear"), h, h),
            self.linear(&format!("{name}.shared.residual.0.fc1"), h, h),
            self.linear(&format!("{name}.shared.residual.0.fc2"), h, h),
            self.linear(&format!("{name}.shared.residual.1.fc1"), h, h),
            self.linear(&format!("{name}.shared.residual.1.fc2"), h, h),
            self.linear(&format!("{name}.shared.residual.2.fc1"), h, h),
            self.linear(&format!("{name}.shared.residual.2.fc2"), h, h),
            self.linear(&format!("{name}.shared.out"), 1, h),
        ];
        NetAt { layers }
    }
}

impl Layout {
    /// The layout of a model whose feature network reads `channels` inputs.
    pub fn new(channels: usize) -> Layout {
        let mut b = Builder { entries: Vec::new(), len: 0 };
        let motion = b.net("motion", 2);
        let measurement = b.net("measurement", 2);
        let feature = b.net("feature", channels);
        let input_mean = b.add("feature.input_mean".into(), vec![channels], false);
        let input_std = b.add("feature.input_std".into(), vec![channels], false);
        let process_noise = b.add("process_noise.cholesky".into(), vec![2, 2], true);
        let measurement_noise = b.add("measurement_noise.cholesky".into(), vec![1, 1], true);
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
            len: b.len,
        }
    }

    /// The entry named `name`.
    pub fn entry(&self, name: &str) -> Option<&ParamEntry> {
        self.entries.iter().find(|e| e.name == name)
    }

    /// Fresh parameters: PyTorch's default initialisation of linear layers
    /// (weights and biases uniform in `±1/sqrt(in)`); `L_Q = diag(0.1, 0.3)`,
    /// `L_R = 1`; input normalisation mean 0, std 1.
    pub fn init(&self, rng: &mut impl Rng) -> Vec<f32> {
        let mut p = vec![0.0f32; self.len];
        for net in [&self.motion, &self.measurement, &self.feature] {
            for l in &net.layers {
                let bound = 1.0 / (l.inp as f32).sqrt();
                for v in &mut p[l.weight..l.weight + l.out * l.inp] {
                    *v = rng.random_range(-bound..bound);
                }
                for v in &mut p[l.bias..l.bias + l.out] {
                    *v = rng.random_range(-bound..bound);
                }
            }
        }
        p[self.process_noise] = 0.1;
        p[self.process_noise + 3] = 0.3;
        p[self.measurement_noise] = 1.0;
        for v in &mut p[self.input_std..self.input_std + self.channels] {
            *v = 1.0;
        }
        p
    }

    /// A mask of the trainable elements of the flat vector (the upper triangle
    /// of `process_noise.cholesky` is not trained: `L_Q` is lower-triangular).
    pub fn trainable_mask(&self) -> Vec<bool> {
        let mut mask = vec![false; self.len];
        for e in &self.entries {
            if e.trainable {
                mask[e.range()].iter_mut().for_each(|m| *m = true);
            }
        }
        mask[self.process_noise + 1] = false;
        mask
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
    }
}
