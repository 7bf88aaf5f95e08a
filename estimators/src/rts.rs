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
///
/// A gate alone can lock a filter out: when the state really changes faster
/// than the model allows (an object that falls), every later measurement is
/// beyond the gate and the filter coasts away on its prediction. With
/// `reacquire_after = Some(n)`, after `n` measurements in a row were rejected
/// the gate opens: measurements are accepted whatever their distance until
/// `n` in a row fall inside it again (the filter has caught up), as a run
/// of "outliers" is the state, not noise. Opening for one measurement, or
/// until the first one inside, is not enough: the jump jolts the velocity,
/// and the next positions fall outside the gate on the other side.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Gate {
    /// Largest accepted `y^T S^-1 y` (dimensionless).
    pub max_mahalanobis2: f64,
    /// Rejections in a row after which the gate opens, until as many
    /// measurements in a row are inside it; `None`: never (a measurement
    /// beyond the gate is always rejected).
    pub reacquire_after: Option<u32>,
}

impl Gate {
    /// A gate at `max_mahalanobis2` that never re-acquires.
    pub const fn at(max_mahalanobis2: f64) -> Gate {
        Gate { max_mahalanobis2, reacquire_after: None }
    }
}

/// What a [`Gate`] remembers between measurements.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum GateState {
    /// The last measurement was inside the gate (or there was none yet).
    #[default]
    Closed,
    /// This many measurements in a row were rejected (at least one).
    Rejecting(u32),
    /// Re-acquiring: everything is accepted; this many in a row were inside.
    Open(u32),
}

impl GateState {
    /// Whether `gate` accepts a measurement at `mahalanobis2` (NaN distances
    /// are outside it), and the state after it.
    pub fn admits(&mut self, gate: &Gate, mahalanobis2: f64) -> bool {
        let inside = mahalanobis2 <= gate.max_mahalanobis2;
        let Some(n) = gate.reacquire_after else { return inside };
        let (admitted, next) = match *self {
            GateState::Open(k) if inside && k + 1 >= n => (true, GateState::Closed),
            GateState::Open(k) => (true, GateState::Open(if inside { k + 1 } else { 0 })),
            _ if inside => (true, GateState::Closed),
            GateState::Rejecting(k) if k >= n => (true, GateState::Open(0)),
            GateState::Rejecting(k) => (false, GateState::Rejecting(k + 1)),
            GateState::Closed => (false, GateState::Rejecting(1)),
        };
        *self = next;
        admitted
    }
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
    gate_state: GateState,
}

impl<const N: usize> GatedKalmanFilter<N> {
    /// A filter starting from `initial`, the belief before the first step,
    /// without gating, with the Joseph-form covariance update.
    pub fn new(initial: Gaussian<N>) -> GatedKalmanFilter<N> {
        GatedKalmanFilter {
            belief: initial,
            gate: None,
            form: CovarianceUpdate::Joseph,
            gate_state: GateState::default(),
        }
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
        &mut self,
        prior: &Gaussian<N>,
        m: &Measurement<N, M>,
    ) -> Result<(Gaussian<N>, MeasurementUse), EstimatorError> {
        if !m.z.iter().all(|v| v.is_finite()) {
            return Err(EstimatorError::NonFiniteMeasurement);
        }
        // The gate's next state is kept only once the step has succeeded.
        let mut state = self.gate_state;
        if let Some(gate) = self.gate {
            let mahalanobis2 = innovation(prior, &m.z, &m.H, &m.R)?.mahalanobis2;
            if !state.admits(&gate, mahalanobis2) {
                self.gate_state = state;
                return Ok((*prior, MeasurementUse::Rejected { mahalanobis2 }));
            }
        }
        let (posterior, innov) = update(prior, &m.z, &m.H, &m.R, self.form)?;
        self.gate_state = state;
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
