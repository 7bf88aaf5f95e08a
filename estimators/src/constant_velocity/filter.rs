//! The causal constant-velocity filter, one sample at a time: the live
//! tracker of the marker, and the forward half of the ground truth.

use crate::kf::Gaussian;
use crate::rts::{GatedKalmanFilter, Transition};

use super::params::CvParams;

/// The constant-velocity model run causally: predicted to each sample time
/// and corrected with the position when there is one, finite and inside
/// the gate (the gated Kalman filter of [`crate::rts`], as the smoother's
/// forward pass). It starts at the first measured position, from
/// [`CvParams::initial`].
#[derive(Clone, Copy, Debug)]
pub struct CvFilter {
    params: CvParams,
    /// Time (s) and filter after the last sample; `None` before the first measurement.
    last: Option<(f64, GatedKalmanFilter<2>)>,
}

impl CvFilter {
    /// A filter with the model `params` (SI units), before any sample.
    pub fn new(params: CvParams) -> CvFilter {
        CvFilter { params, last: None }
    }

    /// The model's parameters.
    pub fn params(&self) -> &CvParams {
        &self.params
    }

    /// One sample at `t_s` with the position `z_m` (m) when it was measured
    /// (a NaN or infinite one counts as missing). Returns the belief after
    /// the sample (m, m/s), `None` until a position has been measured once.
    /// A time before the previous sample's predicts over `dt = 0`; a
    /// singular innovation leaves the sample predict-only.
    pub fn step(&mut self, t_s: f64, z_m: Option<f64>) -> Option<Gaussian<2>> {
        let z_m = z_m.filter(|z| z.is_finite());
        let (transition, mut filter) = match self.last {
            None => {
                z_m?;
                let filter = GatedKalmanFilter::new(self.params.initial()).with_gate(self.params.gate);
                (Transition::identity(), filter)
            }
            Some((t0, filter)) => (self.params.transition((t_s - t0).max(0.0)), filter),
        };
        let measurement = z_m.map(|z_m| self.params.measurement(z_m));
        if filter.step(transition, measurement.as_ref()).is_err() {
            let _ = filter.step::<1>(transition, None);
        }
        self.last = Some((t_s, filter));
        Some(*filter.belief())
    }
}
