//! The Rauch-Tung-Striebel smoother (thesis Sec. 2.4.3, Algorithm 10) on top
//! of a linear Kalman filter (Algorithm 1) that keeps, for every step, the
//! transition it used, its prior and its posterior.
//!
//! Generic over the state size `N` and the measurement size `M`. Each step
//! first moves the belief with its own `F`, `Q` (so `dt` may vary per step),
//! then corrects it with a measurement when there is one: a step without a
//! measurement is a predict-only step. An optional innovation gate rejects a
//! measurement whose squared Mahalanobis distance `y^T S^-1 y` exceeds a
//! threshold; a rejected measurement is treated as missing.
#![expect(non_snake_case, reason = "matrices are named as in the thesis's equations (F, H, Q, R, P, K)")]

use nalgebra::{SMatrix, SVector};

use crate::EstimatorError;
use crate::kf::{CovarianceUpdate, Gaussian, innovation, predict, update};

/// The motion of one step: `x_k = F x_{k-1} + w`, `w ~ N(0, Q)` (eq. 2.9).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Transition<const N: usize> {
    /// State transition matrix `F`.
    pub F: SMatrix<f64, N, N>,
    /// Process noise covariance `Q` of this step.
    pub Q: SMatrix<f64, N, N>,
}

impl<const N: usize> Transition<N> {
    /// The transition that leaves the belief as it is (`F = I`, `Q = 0`),
    /// for a first step that only measures.
    pub fn identity() -> Transition<N> {
        Transition { F: SMatrix::identity(), Q: SMatrix::zeros() }
    }
}

/// A linear measurement `z = H x + v`, `v ~ N(0, R)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Measurement<const N: usize, const M: usize> {
    /// The measured value.
    pub z: SVector<f64, M>,
    /// Measurement matrix `H`.
    pub H: SMatrix<f64, M, N>,
    /// Measurement noise covariance `R`.
    pub R: SMatrix<f64, M, M>,
}

/// Innovation gating: a measurement is rejected when the squared Mahalanobis
/// distance of its innovation exceeds `max_mahalanobis2`. For `M` = 1 the
/// distance is in standard deviations of the innovation, so 25 rejects
/// anything beyond 5 sigma (chi-square tail 6e-7).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Gate {
    /// Largest accepted `y^T S^-1 y` (dimensionless).
    pub max_mahalanobis2: f64,
}

/// What a step did with its measurement.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum MeasurementUse {
    /// There was none: the step only predicted.
    Missing,
    /// The measurement corrected the belief.
    Accepted {
        /// Its squared Mahalanobis distance against the prior.
        mahalanobis2: f64,
    },
    /// The gate rejected it: the step only predicted.
    Rejected {
        /// Its squared Mahalanobis distance against the prior.
        mahalanobis2: f64,
    },
}

impl MeasurementUse {
    /// The squared Mahalanobis distance, when there was a measurement.
    pub fn mahalanobis2(&self) -> Option<f64> {
        match *self {
            MeasurementUse::Missing => None,
            MeasurementUse::Accepted { mahalanobis2 } | MeasurementUse::Rejected { mahalanobis2 } => {
                Some(mahalanobis2)
            }
        }
    }
}

/// One step of the forward pass, as the smoother needs it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FilteredStep<const N: usize> {
    /// The transition into this step.
    pub transition: Transition<N>,
    /// `p(x_k | z_1:k-1)`: the prediction (Algorithm 1, lines 2-3).
    pub prior: Gaussian<N>,
    /// `p(x_k | z_1:k)`: after the correction (lines 4-6), or the prior.
    pub posterior: Gaussian<N>,
    /// What happened to the step's measurement.
    pub measurement: MeasurementUse,
}

/// A linear Kalman filter (Algorithm 1) with an optional innovation gate,
/// one step at a time, keeping only its current belief: the causal filter of
/// live tracking, and the forward pass under [`ForwardFilter`].
#[derive(Clone, Copy, Debug)]
pub struct GatedKalmanFilter<const N: usize> {
    belief: Gaussian<N>,
    gate: Option<Gate>,
    form: CovarianceUpdate,
}

impl<const N: usize> GatedKalmanFilter<N> {
    /// A filter starting from `initial`, the belief before the first step,
    /// without gating, with the Joseph-form covariance update.
    pub fn new(initial: Gaussian<N>) -> GatedKalmanFilter<N> {
        GatedKalmanFilter { belief: initial, gate: None, form: CovarianceUpdate::Joseph }
    }

    /// Gates every measurement (see [`Gate`]).
    pub fn with_gate(mut self, gate: Option<Gate>) -> GatedKalmanFilter<N> {
        self.gate = gate;
        self
    }

    /// Uses `form` for the covariance update.
    pub fn with_covariance_update(mut self, form: CovarianceUpdate) -> GatedKalmanFilter<N> {
        self.form = form;
        self
    }

    /// The current belief (the last posterior, or the initial belief).
    pub fn belief(&self) -> &Gaussian<N> {
        &self.belief
    }

    /// One step: predict with `transition`, then correct with `measurement`
    /// unless it is missing or gated out. Fails on a non-finite measurement
    /// or a singular innovation covariance, leaving the filter unchanged.
    pub fn step<const M: usize>(
        &mut self,
        transition: Transition<N>,
        measurement: Option<&Measurement<N, M>>,
    ) -> Result<FilteredStep<N>, EstimatorError> {
        let prior = predict(&self.belief, &transition.F, &transition.Q);
        let (posterior, used) = match measurement {
            None => (prior, MeasurementUse::Missing),
            Some(m) => self.correct(&prior, m)?,
        };
        self.belief = posterior;
        Ok(FilteredStep { transition, prior, posterior, measurement: used })
    }

    fn correct<const M: usize>(
        &self,
        prior: &Gaussian<N>,
        m: &Measurement<N, M>,
    ) -> Result<(Gaussian<N>, MeasurementUse), EstimatorError> {
        if !m.z.iter().all(|v| v.is_finite()) {
            return Err(EstimatorError::NonFiniteMeasurement);
        }
        if let Some(gate) = self.gate {
            let mahalanobis2 = innovation(prior, &m.z, &m.H, &m.R)?.mahalanobis2;
            // NaN distances are rejected too.
            let inside = mahalanobis2 <= gate.max_mahalanobis2;
            if !inside {
                return Ok((*prior, MeasurementUse::Rejected { mahalanobis2 }));
            }
        }
        let (posterior, innov) = update(prior, &m.z, &m.H, &m.R, self.form)?;
        Ok((posterior, MeasurementUse::Accepted { mahalanobis2: innov.mahalanobis2 }))
    }
}

/// The forward Kalman filter, recording every step for [`smooth`].
#[derive(Clone, Debug)]
pub struct ForwardFilter<const N: usize> {
    filter: GatedKalmanFilter<N>,
    steps: Vec<FilteredStep<N>>,
}

impl<const N: usize> ForwardFilter<N> {
    /// A filter starting from `initial`, the belief before the first step,
    /// without gating, with the Joseph-form covariance update.
    pub fn new(initial: Gaussian<N>) -> ForwardFilter<N> {
        ForwardFilter { filter: GatedKalmanFilter::new(initial), steps: Vec::new() }
    }

    /// Gates every measurement (see [`Gate`]).
    pub fn with_gate(mut self, gate: Option<Gate>) -> ForwardFilter<N> {
        self.filter = self.filter.with_gate(gate);
        self
    }

    /// Uses `form` for the covariance update.
    pub fn with_covariance_update(mut self, form: CovarianceUpdate) -> ForwardFilter<N> {
        self.filter = self.filter.with_covariance_update(form);
        self
    }

    /// Room for `n` more steps.
    pub fn reserve(&mut self, n: usize) {
        self.steps.reserve(n);
    }

    /// The current belief (the last posterior, or the initial belief).
    pub fn belief(&self) -> &Gaussian<N> {
        self.filter.belief()
    }

    /// One step of [`GatedKalmanFilter::step`], recorded.
    pub fn step<const M: usize>(
        &mut self,
        transition: Transition<N>,
        measurement: Option<&Measurement<N, M>>,
    ) -> Result<&FilteredStep<N>, EstimatorError> {
        let step = self.filter.step(transition, measurement)?;
        self.steps.push(step);
        // Just pushed: the vector is not empty.
        Ok(&self.steps[self.steps.len() - 1])
    }

    /// The steps so far.
    pub fn steps(&self) -> &[FilteredStep<N>] {
        &self.steps
    }

    /// The steps, consuming the filter.
    pub fn into_steps(self) -> Vec<FilteredStep<N>> {
        self.steps
    }
}

/// The RTS smoother (Algorithm 10, eq. 2.143): `p(x_k | z_1:T)` for every
/// step of a forward pass, from the last step backwards:
///
/// ```text
/// G_k   = P_k F_{k+1}^T (F_{k+1} P_k F_{k+1}^T + Q_{k+1})^-1
/// mu^s_k = mu_k + G_k (mu^s_{k+1} - F_{k+1} mu_k)
/// P^s_k  = P_k + G_k (P^s_{k+1} - F_{k+1} P_k F_{k+1}^T - Q_{k+1}) G_k^T
/// ```
///
/// where `mu_k, P_k` is the posterior of step `k` and the bracket is the
/// prior of step `k + 1` as the forward pass computed it. The last smoothed
/// belief is the last posterior. Fails when a prior covariance is singular
/// (for example `Q = 0` with a singular posterior).
pub fn smooth<const N: usize>(steps: &[FilteredStep<N>]) -> Result<Vec<Gaussian<N>>, EstimatorError> {
    let Some(last) = steps.last() else { return Ok(Vec::new()) };
    let mut smoothed = vec![last.posterior; steps.len()];
    let mut next = last.posterior;
    for k in (0..steps.len() - 1).rev() {
        let (current, following) = (&steps[k], &steps[k + 1]);
        let G = smoother_gain(&current.posterior, following)
            .ok_or(EstimatorError::SingularPrior { step: k + 1 })?;
        let P = &current.posterior.cov;
        let mean = current.posterior.mean + G * (next.mean - following.prior.mean);
        let cov = P + G * (next.cov - following.prior.cov) * G.transpose();
        next = Gaussian { mean, cov: symmetric(cov) };
        smoothed[k] = next;
    }
    Ok(smoothed)
}

/// `G_k = P_k F^T (P^-_{k+1})^-1`, solved through the Cholesky factor of the
/// prior covariance (symmetric positive definite), or its inverse when
/// rounding made it indefinite.
fn smoother_gain<const N: usize>(
    posterior: &Gaussian<N>,
    following: &FilteredStep<N>,
) -> Option<SMatrix<f64, N, N>> {
    // G P^- = P F^T  <=>  P^- G^T = F P  (both covariances symmetric).
    let rhs = following.transition.F * posterior.cov;
    let prior_cov = following.prior.cov;
    let Gt = match prior_cov.cholesky() {
        Some(chol) => chol.solve(&rhs),
        None => prior_cov.try_inverse()? * rhs,
    };
    Gt.iter().all(|v| v.is_finite()).then(|| Gt.transpose())
}

/// `(A + A^T) / 2`: removes the asymmetry rounding leaves.
fn symmetric<const N: usize>(a: SMatrix<f64, N, N>) -> SMatrix<f64, N, N> {
    (a + a.transpose()) * 0.5
}

#[cfg(test)]
mod tests;
