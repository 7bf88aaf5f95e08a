//! The dEKF running online or on replay (dEKF table): the derivative filter
//! on every tactile scan, the dEKF on every `decimation`-th.
#![expect(non_snake_case, reason = "matrices are named as in the thesis's equations (F, H, Q, R, P, K)")]

use super::ekf::{M2, MIN_INNOVATION_VAR, correct, predict};
use super::infer::FastNet;
use super::input::DekfInput;
use super::model::DekfModel;
use super::multi::MultiFilter;
use super::state::StateKind;

/// One estimate of the dEKF.
#[derive(Clone, Debug, PartialEq)]
pub struct DekfOutput {
    /// Time of the scan the estimate belongs to (s).
    pub t_s: f64,
    /// The measurement the feature network read, before normalisation
    /// (derivatives in counts/s, or counts for raw models), in model channel order.
    pub measurement: Vec<f64>,
    /// Mean, `2 dofs` components in the model's state units: `(p, v)` (cm,
    /// cm/s) for a sliding model, `(x, y, theta, vx, vy, omega)` (cm, cm,
    /// deg, cm/s, cm/s, deg/s) for a planar one.
    pub mean: Vec<f64>,
    /// Covariance, `2 dofs` square, row-major.
    pub cov: Vec<f64>,
    /// True when the measurement was used (false: prediction only).
    pub corrected: bool,
}

impl DekfOutput {
    /// Components of the state.
    pub fn dim(&self) -> usize {
        self.mean.len()
    }

    /// Element `(r, c)` of the covariance.
    pub fn cov_at(&self, r: usize, c: usize) -> f64 {
        self.cov[r * self.dim() + c]
    }
}

/// The dEKF with its derivative filter, for a model of any state.
pub struct DekfTracker {
    input: DekfInput,
    filter: Filter,
}

/// The filter of a model's state: the thesis's with its fast scalar
/// networks, or the vector filter of [`super::multi`].
enum Filter {
    Sliding(Box<SlidingFilter>),
    Planar(Box<MultiFilter<6, 3>>),
}

impl DekfTracker {
    /// A tracker for `model`, at `mu0 = 0`, `P0` from the model.
    pub fn new(model: &DekfModel) -> DekfTracker {
        let filter = match model.state() {
            StateKind::Sliding => Filter::Sliding(Box::new(SlidingFilter::new(model))),
            StateKind::Planar => Filter::Planar(Box::new(MultiFilter::new(model))),
        };
        DekfTracker { input: DekfInput::for_model(model), filter }
    }

    /// The current mean and covariance (row-major), in the model's state units.
    pub fn state(&self) -> (Vec<f64>, Vec<f64>) {
        match &self.filter {
            Filter::Sliding(f) => (f.mean.to_vec(), f.cov.iter().flatten().copied().collect()),
            Filter::Planar(f) => f.state(),
        }
    }

    /// Feeds one tactile scan: baseline-subtracted values (counts) in the
    /// model's channel order, at `t_s`. Returns an estimate on the first scan
    /// (the initial state) and on every `decimation`-th scan after it. A
    /// non-finite value is a missing sample: the derivative filter predicts
    /// for that channel and, if a value the feature network reads is not
    /// finite, the dEKF only predicts.
    pub fn on_scan(&mut self, t_s: f64, zeroed: &[f64]) -> Option<DekfOutput> {
        let step = self.input.on_scan(t_s, zeroed)?;
        let corrected = if step.index == 0 { false } else { self.step(&step.measurement) };
        let (mean, cov) = self.state();
        Some(DekfOutput { t_s, measurement: step.measurement, mean, cov, corrected })
    }

    /// One dEKF step (prediction over `dt`, correction with `measurement`,
    /// unnormalised, in model channel order). Returns whether it corrected.
    pub fn step(&mut self, measurement: &[f64]) -> bool {
        match &mut self.filter {
            Filter::Sliding(f) => f.step(measurement),
            Filter::Planar(f) => f.step(measurement),
        }
    }

    /// Back to `mu0 = 0`, `P0`, with fresh derivative filters.
    pub fn reset(&mut self) {
        self.input.reset();
        match &mut self.filter {
            Filter::Sliding(f) => f.reset(),
            Filter::Planar(f) => f.reset(),
        }
    }
}

/// The thesis's filter with the fast scalar networks of [`FastNet`].
struct SlidingFilter {
    motion: FastNet,
    measurement_net: FastNet,
    feature: FastNet,
    Q: M2,
    R: f64,
    dt: f64,
    norm_mean: Vec<f32>,
    norm_std: Vec<f32>,
    p0: [f64; 2],
    mean: [f64; 2],
    cov: M2,
    buf: Vec<f32>,
}

impl SlidingFilter {
    fn new(model: &DekfModel) -> SlidingFilter {
        let l = &model.layout;
        let (m, s) = model.input_normalisation();
        let p0 = [model.meta.p0_diag[0], model.meta.p0_diag[1]];
        SlidingFilter {
            motion: FastNet::new(&model.params, &l.motion),
            measurement_net: FastNet::new(&model.params, &l.measurement),
            feature: FastNet::new(&model.params, &l.feature),
            Q: model.process_noise(),
            R: model.measurement_noise(),
            dt: model.meta.dt_s,
            norm_mean: m.to_vec(),
            norm_std: s.to_vec(),
            p0,
            mean: [0.0; 2],
            cov: [[p0[0], 0.0], [0.0, p0[1]]],
            buf: vec![0.0; l.channels],
        }
    }

    fn step(&mut self, measurement: &[f64]) -> bool {
        let (a, [j0, j1]) = self.motion.value_and_gradient([self.mean[0] as f32, self.mean[1] as f32]);
        let pred =
            predict(self.mean, &self.cov, f64::from(a), [f64::from(j0), f64::from(j1)], self.dt, &self.Q);
        self.mean = pred.mean;
        self.cov = pred.cov;
        if !measurement.iter().all(|v| v.is_finite()) {
            return false;
        }
        for (c, v) in measurement.iter().enumerate() {
            self.buf[c] = (*v as f32 - self.norm_mean[c]) / self.norm_std[c];
        }
        let z = f64::from(self.feature.value(&self.buf));
        let x = [pred.mean[0] as f32, pred.mean[1] as f32];
        let (zhat, [h0, h1]) = self.measurement_net.value_and_gradient(x);
        let H = [f64::from(h0), f64::from(h1)];
        let S = H[0] * (pred.cov[0][0] * H[0] + pred.cov[0][1] * H[1])
            + H[1] * (pred.cov[1][0] * H[0] + pred.cov[1][1] * H[1])
            + self.R;
        if S.is_nan() || S <= MIN_INNOVATION_VAR {
            return false;
        }
        let c = correct(pred.mean, &pred.cov, z, f64::from(zhat), H, self.R);
        if !(c.mean.iter().all(|v| v.is_finite()) && c.cov.iter().flatten().all(|v| v.is_finite())) {
            return false;
        }
        self.mean = c.mean;
        self.cov = c.cov;
        true
    }

    fn reset(&mut self) {
        self.mean = [0.0; 2];
        self.cov = [[self.p0[0], 0.0], [0.0, self.p0[1]]];
    }
}
