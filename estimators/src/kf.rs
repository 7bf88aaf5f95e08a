//! The linear Kalman filter (thesis Algorithm 1), generic over the state
//! size `N` and the measurement size `M`: the model gives `F` and `Q` per
//! step (so `dt` may vary), and a step without a measurement only predicts.
#![expect(non_snake_case, reason = "matrices are named as in the thesis's equations (F, H, Q, R, P, K)")]

use nalgebra::{SMatrix, SVector};

use crate::EstimatorError;

/// A Gaussian belief: mean and covariance.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Gaussian<const N: usize> {
    /// Mean.
    pub mean: SVector<f64, N>,
    /// Covariance (symmetric, positive semi-definite).
    pub cov: SMatrix<f64, N, N>,
}

impl<const N: usize> Gaussian<N> {
    /// A belief from its mean and covariance.
    pub fn new(mean: SVector<f64, N>, cov: SMatrix<f64, N, N>) -> Gaussian<N> {
        Gaussian { mean, cov }
    }
}

/// How the covariance is updated after a measurement.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum CovarianceUpdate {
    /// `P = (I - K H) P (I - K H)^T + K R K^T`: stays symmetric and positive
    /// semi-definite under rounding.
    #[default]
    Joseph,
    /// `P = (I - K H) P`: the textbook form, cheaper.
    Simple,
}

/// The innovation of one update, for gating and diagnostics.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Innovation<const M: usize> {
    /// `y = z - H x`.
    pub residual: SVector<f64, M>,
    /// `S = H P H^T + R`.
    pub cov: SMatrix<f64, M, M>,
    /// Squared Mahalanobis distance `y^T S^-1 y`.
    pub mahalanobis2: f64,
}

/// Prediction `x' = F x`, `P' = F P F^T + Q` (Algorithm 1, lines 2-3).
pub fn predict<const N: usize>(
    belief: &Gaussian<N>,
    F: &SMatrix<f64, N, N>,
    Q: &SMatrix<f64, N, N>,
) -> Gaussian<N> {
    Gaussian { mean: F * belief.mean, cov: F * belief.cov * F.transpose() + Q }
}

/// The innovation of measurement `z` against the prior `belief`.
pub fn innovation<const N: usize, const M: usize>(
    belief: &Gaussian<N>,
    z: &SVector<f64, M>,
    H: &SMatrix<f64, M, N>,
    R: &SMatrix<f64, M, M>,
) -> Result<Innovation<M>, EstimatorError> {
    let residual = z - H * belief.mean;
    let cov = H * belief.cov * H.transpose() + R;
    let inv = cov.try_inverse().ok_or(EstimatorError::SingularInnovation)?;
    let mahalanobis2 = (residual.transpose() * inv * residual)[(0, 0)];
    Ok(Innovation { residual, cov, mahalanobis2 })
}

/// Correction with measurement `z = H x + v`, `v ~ N(0, R)` (Algorithm 1,
/// lines 4-6). Returns the posterior and the innovation it used.
pub fn update<const N: usize, const M: usize>(
    belief: &Gaussian<N>,
    z: &SVector<f64, M>,
    H: &SMatrix<f64, M, N>,
    R: &SMatrix<f64, M, M>,
    form: CovarianceUpdate,
) -> Result<(Gaussian<N>, Innovation<M>), EstimatorError> {
    if !z.iter().all(|v| v.is_finite()) {
        return Err(EstimatorError::NonFiniteMeasurement);
    }
    let innov = innovation(belief, z, H, R)?;
    let S_inv = innov.cov.try_inverse().ok_or(EstimatorError::SingularInnovation)?;
    let K = belief.cov * H.transpose() * S_inv;
    let mean = belief.mean + K * innov.residual;
    let I_KH = SMatrix::<f64, N, N>::identity() - K * H;
    let cov = match form {
        CovarianceUpdate::Joseph => I_KH * belief.cov * I_KH.transpose() + K * R * K.transpose(),
        CovarianceUpdate::Simple => I_KH * belief.cov,
    };
    Ok((Gaussian { mean, cov }, innov))
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn scalar_update_is_the_weighted_mean() {
        // Prior N(1, 4), measurement 3 with variance 1: posterior mean
        // (1/4 + 3/1) / (1/4 + 1) = 2.6, variance 0.8.
        let prior = Gaussian::new(SVector::<f64, 1>::new(1.0), SMatrix::<f64, 1, 1>::new(4.0));
        let H = SMatrix::<f64, 1, 1>::identity();
        let R = SMatrix::<f64, 1, 1>::new(1.0);
        for form in [CovarianceUpdate::Joseph, CovarianceUpdate::Simple] {
            let (post, innov) = update(&prior, &SVector::<f64, 1>::new(3.0), &H, &R, form).unwrap();
            assert_relative_eq!(post.mean[0], 2.6, epsilon = 1e-12);
            assert_relative_eq!(post.cov[(0, 0)], 0.8, epsilon = 1e-12);
            assert_relative_eq!(innov.mahalanobis2, 4.0 / 5.0, epsilon = 1e-12);
        }
    }

    #[test]
    fn non_finite_measurements_are_refused() {
        let b = Gaussian::new(SVector::<f64, 2>::zeros(), SMatrix::<f64, 2, 2>::identity());
        let H = SMatrix::<f64, 1, 2>::new(1.0, 0.0);
        let R = SMatrix::<f64, 1, 1>::new(1.0);
        let z = SVector::<f64, 1>::new(f64::INFINITY);
        assert!(update(&b, &z, &H, &R, CovarianceUpdate::Joseph).is_err());
    }
}
