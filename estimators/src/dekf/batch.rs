//! What a batch gradient runs on (training sequences and the windows cut
//! from them) and what it returns, for the sliding filter's [`super::batch_grad`]
//! and the vector filter's.

/// A training sequence at the filter's rate.
#[derive(Clone, Debug, PartialEq)]
pub struct Sequence {
    /// Normalised feature-network inputs, `len x channels`, row-major.
    pub measurements: Vec<f32>,
    /// Whether step `t` has a usable measurement.
    pub valid: Vec<bool>,
    /// Ground-truth state per step, `dim` components each, step after step:
    /// `(p, v)` (cm, cm/s) for a sliding model (see [`super::StateKind`]).
    pub truth: Vec<f64>,
    /// Components of the state.
    pub dim: usize,
}

impl Sequence {
    /// A sequence of a two-component (sliding) state from `(p, v)` per step.
    pub fn sliding(measurements: Vec<f32>, valid: Vec<bool>, truth: &[[f64; 2]]) -> Sequence {
        Sequence { measurements, valid, truth: truth.iter().flatten().copied().collect(), dim: 2 }
    }

    /// Number of steps.
    pub fn len(&self) -> usize {
        self.valid.len()
    }

    /// True for a sequence without steps.
    pub fn is_empty(&self) -> bool {
        self.valid.is_empty()
    }

    /// The ground-truth state at step `t`.
    pub fn truth_at(&self, t: usize) -> &[f64] {
        &self.truth[t * self.dim..(t + 1) * self.dim]
    }
}

/// One subsequence of a batch: sequence index, start step and initial state.
#[derive(Clone, Debug, PartialEq)]
pub struct Window {
    /// Index of the sequence.
    pub sequence: usize,
    /// First step `t0`; the filter starts there and steps to `t0 + T_s`.
    pub start: usize,
    /// Initial mean, drawn from `N(x_gt(t0), P0)` (2.148), with the window's
    /// position shift added (one value per state component).
    pub mean0: Vec<f64>,
    /// Added to the ground-truth positions of every step of the window, one
    /// per degree of freedom (cm; deg for a rotation): the whole window
    /// moved (0: as recorded).
    pub position_shift: Vec<f64>,
}

/// Loss and gradient of a batch (or a shard of it).
#[derive(Clone, Debug, PartialEq)]
pub struct BatchGrad {
    /// Sum over windows and steps of the squared state error `|x_gt - mu|^2`.
    pub squared_error: f64,
    /// The same split into position and velocity.
    pub squared_error_pv: [f64; 2],
    /// Number of corrected states compared.
    pub states: usize,
    /// Gradient of the sum of squared errors (not yet divided by `T_s B n`).
    pub grad: Vec<f32>,
}
