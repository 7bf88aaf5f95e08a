//! The dEKF's input pipeline (dEKF table, steps 7-9): on every tactile scan
//! the per-channel derivative filter, and every `decimation`-th scan from the
//! first a filter step with the measurement the feature network reads. The
//! online filter ([`DekfTracker`](super::DekfTracker)) and the preparation of
//! training data both go through it, so they cannot disagree.

use super::model::{DekfModel, Measurement};
use crate::derivative::{DerivativeFilter, DerivativeFilterConfig};

/// One filter step of [`DekfInput`].
#[derive(Clone, Debug, PartialEq)]
pub struct InputStep {
    /// Filter steps before this one (0 for the first scan).
    pub index: u64,
    /// The measurement, unnormalised, in model channel order: derivatives
    /// (counts/s) or baseline-subtracted values (counts).
    pub measurement: Vec<f64>,
}

/// The derivative filter and the decimation in front of the dEKF.
pub struct DekfInput {
    derivative: DerivativeFilter,
    kind: Measurement,
    decimation: u64,
    scans: u64,
}

impl DekfInput {
    /// The pipeline of `kind` over `channels` channels, keeping every
    /// `decimation`-th scan (at least every scan).
    pub fn new(
        kind: Measurement,
        filter: DerivativeFilterConfig,
        channels: usize,
        decimation: usize,
    ) -> DekfInput {
        DekfInput {
            derivative: DerivativeFilter::new(filter, channels),
            kind,
            decimation: decimation.max(1) as u64,
            scans: 0,
        }
    }

    /// The pipeline `model` was trained with.
    pub fn for_model(model: &DekfModel) -> DekfInput {
        let m = &model.meta;
        DekfInput::new(m.measurement, m.derivative_filter, model.layout.channels, m.decimation)
    }

    /// Feeds one scan at `t_s` (s): baseline-subtracted values (counts) in
    /// the model's channel order, non-finite for a missing sample. Returns
    /// the filter step on the first scan and every `decimation`-th after it.
    pub fn on_scan(&mut self, t_s: f64, zeroed: &[f64]) -> Option<InputStep> {
        let derivatives = self.derivative.step(t_s, zeroed);
        let k = self.scans;
        self.scans += 1;
        if !k.is_multiple_of(self.decimation) {
            return None;
        }
        let measurement = match self.kind {
            Measurement::Derivative => derivatives.to_vec(),
            Measurement::Raw => zeroed.to_vec(),
        };
        Some(InputStep { index: k / self.decimation, measurement })
    }

    /// Back to the first scan, with fresh derivative filters.
    pub fn reset(&mut self) {
        let cfg = *self.derivative.config();
        self.derivative = DerivativeFilter::new(cfg, self.derivative_channels());
        self.scans = 0;
    }

    fn derivative_channels(&self) -> usize {
        self.derivative.channels()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_decimation_th_scan_is_a_step_from_the_first() {
        let mut input = DekfInput::new(Measurement::Raw, DerivativeFilterConfig::default(), 1, 3);
        let steps: Vec<(u64, f64)> = (0..10)
            .filter_map(|k| input.on_scan(k as f64 * 0.01, &[k as f64]).map(|s| (s.index, s.measurement[0])))
            .collect();
        assert_eq!(steps, [(0, 0.0), (1, 3.0), (2, 6.0), (3, 9.0)]);
        input.reset();
        assert_eq!(input.on_scan(5.0, &[7.0]).map(|s| s.index), Some(0), "a reset starts over");
    }
}
