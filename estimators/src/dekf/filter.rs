//! The dEKF running online or on replay (dEKF table): the derivative filter
//! on every tactile scan, the dEKF on every `decimation`-th.
#![expect(non_snake_case, reason = "matrices are named as in the thesis's equations (F, H, Q, R, P, K)")]

use super::ekf::{M2, correct, predict};
use super::infer::FastNet;
use super::input::DekfInput;
use super::model::DekfModel;

/// Smallest innovation variance `S` for which the filter corrects; below it
/// the measurement carries no usable information and the step only predicts.
pub const MIN_INNOVATION_VAR: f64 = 1e-12;

/// One estimate of the dEKF.
#[derive(Clone, Debug, PartialEq)]
pub struct DekfOutput {
    /// Time of the scan the estimate belongs to (s).
    pub t_s: f64,
    /// The measurement the feature network read, before normalisation
    /// (derivatives in counts/s, or counts for raw models), in model channel order.
    pub measurement: Vec<f64>,
    /// Mean `(p, v)` (cm, cm/s).
    pub mean: [f64; 2],
    /// Covariance (cm^2, cm^2/s, cm^2/s^2).
    pub cov: M2,
    /// True when the measurement was used (false: prediction only).
    pub corrected: bool,
}

/// The dEKF with its derivative filter.
pub struct DekfTracker {
    motion: FastNet,
    measurement_net: FastNet,
    feature: FastNet,
    Q: M2,
    R: f64,
    dt: f64,
    norm_mean: Vec<f32>,
    norm_std: Vec<f32>,
    p0: [f64; 2],
    input: DekfInput,
    mean: [f64; 2],
    cov: M2,
    buf: Vec<f32>,
}

impl DekfTracker {
    /// A tracker for `model`, at `mu0 = 0`, `P0` from the model.
    pub fn new(model: &DekfModel) -> DekfTracker {
        let l = &model.layout;
        let (m, s) = model.input_normalisation();
        let p0 = model.meta.p0_diag;
        DekfTracker {
            motion: FastNet::new(&model.params, &l.motion),
            measurement_net: FastNet::new(&model.params, &l.measurement),
            feature: FastNet::new(&model.params, &l.feature),
            Q: model.process_noise(),
            R: model.measurement_noise(),
            dt: model.meta.dt_s,
            norm_mean: m.to_vec(),
            norm_std: s.to_vec(),
            p0,
            input: DekfInput::for_model(model),
            mean: [0.0; 2],
            cov: [[p0[0], 0.0], [0.0, p0[1]]],
            buf: vec![0.0; l.channels],
        }
    }

    /// The current mean `(p, v)` (cm, cm/s) and covariance.
    pub fn state(&self) -> ([f64; 2], M2) {
        (self.mean, self.cov)
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
        Some(DekfOutput { t_s, measurement: step.measurement, mean: self.mean, cov: self.cov, corrected })
    }

    /// One dEKF step (prediction over `dt`, correction with `measurement`,
    /// unnormalised, in model channel order). Returns whether it corrected.
    pub fn step(&mut self, measurement: &[f64]) -> bool {
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

    /// Back to `mu0 = 0`, `P0`, with fresh derivative filters.
    pub fn reset(&mut self) {
        self.input.reset();
        self.mean = [0.0; 2];
        self.cov = [[self.p0[0], 0.0], [0.0, self.p0[1]]];
    }
}
