//! The linear Kalman filter (thesis Algorithm 1), generic over the state
//! size `N` and the measurement size `M`, with `dt` passed per step and
//! `None` for a missing measurement (predict only).
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

/// The constant-velocity model of a scalar quantity, state `(position,
/// velocity)` (eq. 6.13): `F = [[1, dt], [0, 1]]`, measurement `H = [1, 0]`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ConstantVelocity {
    /// Process noise covariance added at each step, `diag(q_position, q_velocity)`
    /// in (unit^2, (unit/s)^2).
    pub q_diag: [f64; 2],
    /// Measurement noise variance (unit^2).
    pub r: f64,
}

impl Default for ConstantVelocity {
    /// The thesis's ground-truth smoother (Sec. 6.2.3): `Q = diag(0.01, 0.01)`
    /// per step and `R = 10`, in the squares of whatever length unit the
    /// measurements use (only the ratios of `Q`, `R` and `P0` shape the
    /// smoothed mean). [`crate::cv_smoother::CvSmootherParams::default`]
    /// holds the same values as rates in SI units, read in cm at 30 Hz steps.
    fn default() -> Self {
        ConstantVelocity { q_diag: [0.01, 0.01], r: 10.0 }
    }
}

impl ConstantVelocity {
    /// `F(dt)`.
    #[rustfmt::skip]
    pub fn F(dt_s: f64) -> SMatrix<f64, 2, 2> {
        SMatrix::<f64, 2, 2>::new(
            1.0, dt_s,
            0.0, 1.0,
        )
    }

    /// `H`: the position is measured.
    pub fn H() -> SMatrix<f64, 1, 2> {
        SMatrix::<f64, 1, 2>::new(1.0, 0.0)
    }

    /// `Q`.
    pub fn Q(&self) -> SMatrix<f64, 2, 2> {
        SMatrix::<f64, 2, 2>::from_diagonal(&SVector::<f64, 2>::new(self.q_diag[0], self.q_diag[1]))
    }

    /// `R`.
    pub fn R(&self) -> SMatrix<f64, 1, 1> {
        SMatrix::<f64, 1, 1>::new(self.r)
    }

    /// One step: predict over `dt_s`, then correct with `z` when present and
    /// finite (a missing or non-finite measurement is a predict-only step).
    pub fn step(&self, belief: &Gaussian<2>, dt_s: f64, z: Option<f64>) -> Gaussian<2> {
        let prior = predict(belief, &Self::F(dt_s), &self.Q());
        match z.filter(|v| v.is_finite()) {
            Some(z) => {
                update(&prior, &SVector::<f64, 1>::new(z), &Self::H(), &self.R(), CovarianceUpdate::Joseph)
                    .map_or(prior, |(post, _)| post)
            }
            None => prior,
        }
    }
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
    fn constant_velocity_without_noise_extrapolates_exactly() {
        let cv = ConstantVelocity { q_diag: [0.0, 0.0], r: 1.0 };
        let mut b = Gaussian::new(SVector::<f64, 2>::new(1.0, 2.0), SMatrix::<f64, 2, 2>::zeros());
        for _ in 0..10 {
            b = cv.step(&b, 0.1, None);
        }
        assert_relative_eq!(b.mean[0], 3.0, epsilon = 1e-12);
        assert_relative_eq!(b.mean[1], 2.0, epsilon = 1e-12);
    }

    #[test]
    fn a_steady_ramp_is_tracked_with_its_slope() {
        let cv = ConstantVelocity { q_diag: [1e-6, 1e-4], r: 0.01 };
        let mut b = Gaussian::new(SVector::<f64, 2>::zeros(), SMatrix::<f64, 2, 2>::identity());
        for k in 1..=500 {
            let t = k as f64 * 0.01;
            b = cv.step(&b, 0.01, Some(0.5 * t));
        }
        assert_relative_eq!(b.mean[1], 0.5, epsilon = 1e-3);
    }

    #[test]
    fn non_finite_measurements_are_refused_and_skipped() {
        let cv = ConstantVelocity { q_diag: [0.01, 0.01], r: 1.0 };
        let b = Gaussian::new(SVector::<f64, 2>::zeros(), SMatrix::<f64, 2, 2>::identity());
        let skipped = cv.step(&b, 0.1, Some(f64::NAN));
        let predicted = cv.step(&b, 0.1, None);
        assert_eq!(skipped, predicted);
        let H = ConstantVelocity::H();
        let z = SVector::<f64, 1>::new(f64::INFINITY);
        assert!(update(&b, &z, &H, &cv.R(), CovarianceUpdate::Joseph).is_err());
    }
}
