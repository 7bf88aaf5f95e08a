//! [`LinearMap`]: the fitted map and how it is applied.

use nalgebra::{DMatrix, DVector};

/// A fitted linear map from input channels to outputs.
#[derive(Clone, Debug, PartialEq)]
pub struct LinearMap {
    /// Names of the input channels, in the order [`LinearMap::apply`] reads them.
    pub input_names: Vec<String>,
    /// Names of the outputs (with units, e.g. `position_cm`), in the order written.
    pub output_names: Vec<String>,
    /// Mean `μ` of each input over the training rows.
    pub input_mean: Vec<f64>,
    /// Population standard deviation `σ` of each input over the training
    /// rows; 1 for a constant input. Always positive.
    pub input_std: Vec<f64>,
    /// Mean `ȳ` of each output over the training rows.
    pub output_mean: Vec<f64>,
    /// `W`, `[outputs, inputs]`: the weights on standardised inputs.
    pub weights: DMatrix<f64>,
    /// The ridge penalty `λ_o` chosen for each output.
    pub lambda: Vec<f64>,
    /// Free-form: what the map was fitted on, its cross-validation scores, ...
    /// [`LinearMap::fit`] stores its [`FitReport`](super::FitReport) under `"fit"`.
    pub meta: serde_json::Value,
}

impl LinearMap {
    /// Number of input channels.
    pub fn inputs(&self) -> usize {
        self.input_names.len()
    }

    /// Number of outputs.
    pub fn outputs(&self) -> usize {
        self.output_names.len()
    }

    /// `y = ȳ + W (x − μ)/σ` for one sample. Allocation-free. An input that
    /// is NaN or infinite makes every output NaN.
    ///
    /// # Panics
    /// If `input` or `output` does not have the map's width (a caller bug).
    pub fn apply(&self, input: &[f64], output: &mut [f64]) {
        assert_eq!(input.len(), self.inputs(), "LinearMap::apply: input width");
        assert_eq!(output.len(), self.outputs(), "LinearMap::apply: output width");
        if input.iter().any(|x| !x.is_finite()) {
            output.fill(f64::NAN);
            return;
        }
        for (o, y) in output.iter_mut().enumerate() {
            let mut sum = 0.0;
            for (i, x) in input.iter().enumerate() {
                sum += self.weights[(o, i)] * ((x - self.input_mean[i]) / self.input_std[i]);
            }
            *y = self.output_mean[o] + sum;
        }
    }

    /// The map in the original input units, `y = W' x + b`: `W'`
    /// `[outputs, inputs]` and `b` `[outputs]` (what the file stores as
    /// `linear.weight` and `linear.bias`).
    pub fn affine(&self) -> (DMatrix<f64>, DVector<f64>) {
        let w =
            DMatrix::from_fn(self.outputs(), self.inputs(), |o, i| self.weights[(o, i)] / self.input_std[i]);
        let b = DVector::from_fn(self.outputs(), |o, _| {
            let shift: f64 = (0..self.inputs()).map(|i| w[(o, i)] * self.input_mean[i]).sum();
            self.output_mean[o] - shift
        });
        (w, b)
    }
}
