//! The Kalman filter and RTS smoother of the constant-velocity model over a
//! whole sequence: marker positions into ground truth (eq. 6.15).

use crate::EstimatorError;
use crate::kf::Gaussian;
use crate::rts::{ForwardFilter, MeasurementUse, Transition, smooth};

use super::params::CvParams;

impl CvParams {
    /// Runs the forward filter and the RTS smoother over `samples` (times
    /// strictly increasing). Fails on a time that does not increase or is
    /// not finite, a non-finite measurement, or singular covariances.
    pub fn smooth(&self, samples: &[CvSample]) -> Result<CvTrack, EstimatorError> {
        let mut filter = ForwardFilter::new(self.initial()).with_gate(self.gate);
        filter.reserve(samples.len());
        let mut previous_t_s: Option<f64> = None;
        for (index, sample) in samples.iter().enumerate() {
            let t_s = sample.t_s;
            let transition = match previous_t_s {
                _ if !t_s.is_finite() => return Err(EstimatorError::TimeNotIncreasing { index, t_s }),
                None => Transition::identity(),
                Some(prev) if t_s > prev => self.transition(t_s - prev),
                Some(_) => return Err(EstimatorError::TimeNotIncreasing { index, t_s }),
            };
            let measurement = sample.z_m.map(|z_m| self.measurement(z_m));
            filter.step(transition, measurement.as_ref())?;
            previous_t_s = Some(t_s);
        }
        let steps = filter.into_steps();
        let smoothed = smooth(&steps)?;
        Ok(CvTrack {
            filtered: steps.iter().map(|s| s.posterior).collect(),
            measurements: steps.iter().map(|s| s.measurement).collect(),
            smoothed,
        })
    }
}

/// One sample time, with the marker position measured there if any.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CvSample {
    /// Time (s).
    pub t_s: f64,
    /// Measured position (m), `None` for a predict-only step.
    pub z_m: Option<f64>,
}

/// The filter's and the smoother's beliefs at every sample.
#[derive(Clone, Debug, PartialEq)]
pub struct CvTrack {
    /// `p(x_k | z_1:k)`: the Kalman filter's estimate (causal).
    pub filtered: Vec<Gaussian<2>>,
    /// `p(x_k | z_1:T)`: the smoother's estimate, the ground truth (eq. 6.15).
    pub smoothed: Vec<Gaussian<2>>,
    /// What each sample's measurement was used for.
    pub measurements: Vec<MeasurementUse>,
}
