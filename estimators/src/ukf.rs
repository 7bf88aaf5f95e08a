//! The Unscented Kalman filter (thesis Algorithm 5), on any [`Manifold`]:
//! Euclidean vectors ([`DVector`]), or [`crate::orientation::Composite`]
//! states and measurements with angle (Algorithm 8) and unit-quaternion
//! (Algorithm 9) blocks. Sizes are dynamic; `dt` and the noise covariances are
//! chosen per step by the caller through the model closures and matrices.
//!
//! - [`predict`]: prediction with the augmented variable `(x, w)`, (2.41)-(2.43).
//! - [`correct`]: correction with the augmented variable `(x, ν)`, (2.44)-(2.46).
//! - [`predict_additive`]: prediction for `x_t = f(x_{t-1}) + w`, `Q` added to
//!   the sigma-point covariance (the additive form of Sec. 2.2.3).
//!
//! The correction for additive noise in statistical-Jacobian form and its
//! sequential version are in [`crate::seq_ukf`].
//!
//! Every function returns an error instead of a non-finite belief, so a
//! caller that keeps its previous belief on error never holds NaN.
#![expect(non_snake_case, reason = "matrices are named as in the thesis's equations (F, H, Q, R, P, K)")]

use nalgebra::{DMatrix, DVector, SymmetricEigen};

use crate::EstimatorError;

/// A space the UKF can run on: points with a tangent space of `dof()`
/// dimensions, a "sum" `⊕` with a tangent vector, a "difference" `⊖` and a
/// weighted mean (thesis Sec. 2.3). For Euclidean vectors these are `+`, `-`
/// and `Σ w_i x_i`.
pub trait Manifold: Clone + std::fmt::Debug {
    /// Degrees of freedom: the size of tangent vectors and covariances.
    fn dof(&self) -> usize;
    /// `self ⊕ delta`, `delta.len() == dof()`.
    fn oplus(&self, delta: &[f64]) -> Self;
    /// `self ⊖ other`, a tangent vector of `dof()` entries.
    fn ominus(&self, other: &Self) -> DVector<f64>;
    /// The weighted mean of `points`, `None` when undefined (no points,
    /// lengths differ, or the weighted directions cancel).
    fn weighted_mean(points: &[Self], weights: &[f64]) -> Option<Self>;
    /// All coordinates are finite.
    fn is_finite(&self) -> bool;
}

impl Manifold for DVector<f64> {
    fn dof(&self) -> usize {
        self.len()
    }

    fn oplus(&self, delta: &[f64]) -> DVector<f64> {
        self + DVector::from_column_slice(delta)
    }

    fn ominus(&self, other: &DVector<f64>) -> DVector<f64> {
        self - other
    }

    fn weighted_mean(points: &[DVector<f64>], weights: &[f64]) -> Option<DVector<f64>> {
        let first = points.first()?;
        if points.len() != weights.len() || points.iter().any(|p| p.len() != first.len()) {
            return None;
        }
        let mut mean = DVector::zeros(first.len());
        for (p, w) in points.iter().zip(weights) {
            mean.axpy(*w, p, 1.0);
        }
        Some(mean)
    }

    fn is_finite(&self) -> bool {
        self.iter().all(|v| v.is_finite())
    }
}

/// A Gaussian belief on a manifold: the mean and the covariance of the
/// tangent-space deviation (`dof x dof`).
#[derive(Clone, Debug, PartialEq)]
pub struct Belief<S> {
    /// Mean `μ`.
    pub mean: S,
    /// Covariance `P` in the tangent space at the mean.
    pub cov: DMatrix<f64>,
}

impl<S: Manifold> Belief<S> {
    /// A belief from its mean and covariance; fails when the sizes disagree
    /// or anything is non-finite.
    pub fn new(mean: S, cov: DMatrix<f64>) -> Result<Belief<S>, EstimatorError> {
        let n = mean.dof();
        if cov.nrows() != n || cov.ncols() != n {
            return Err(EstimatorError::DimensionMismatch {
                what: "covariance",
                expected: n,
                got: cov.nrows(),
            });
        }
        let belief = Belief { mean, cov };
        belief.check("belief")?;
        Ok(belief)
    }

    /// Errors unless mean and covariance are finite and the covariance
    /// diagonal is non-negative.
    pub fn check(&self, what: &'static str) -> Result<(), EstimatorError> {
        let cov_ok = self.cov.iter().all(|v| v.is_finite()) && self.cov.diagonal().iter().all(|v| *v >= 0.0);
        if self.mean.is_finite() && cov_ok { Ok(()) } else { Err(EstimatorError::NonFiniteState { what }) }
    }
}

/// The scaling parameters of the unscented transform, (2.39)-(2.40).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct UtParams {
    /// Spread of the sigma points around the mean.
    pub alpha: f64,
    /// Prior knowledge of the distribution (2 is optimal for Gaussians).
    pub beta: f64,
    /// Secondary scaling.
    pub kappa: f64,
}

impl Default for UtParams {
    /// `α = 1, β = 2, κ = 0`: `λ = 0`, every weight non-negative (as the
    /// statistical-Jacobian form of the sequential UKF requires).
    fn default() -> UtParams {
        UtParams { alpha: 1.0, beta: 2.0, kappa: 0.0 }
    }
}

/// The sigma-point weights for an `ñ`-dimensional variable.
#[derive(Clone, Debug, PartialEq)]
pub struct UtWeights {
    /// `λ = α²(ñ + κ) - ñ` (2.39).
    pub lambda: f64,
    /// `sqrt(ñ + λ)`, the scale of the square-root columns.
    pub spread: f64,
    /// Mean weights `W^(m)` (2.40), `2ñ + 1` of them.
    pub wm: Vec<f64>,
    /// Covariance weights `W^(c)` (2.40).
    pub wc: Vec<f64>,
}

impl UtWeights {
    /// Weights of (2.39)-(2.40) for dimension `n_tilde`. Fails when
    /// `ñ + λ <= 0` (no real sigma points).
    pub fn new(n_tilde: usize, p: &UtParams) -> Result<UtWeights, EstimatorError> {
        let n = n_tilde as f64;
        let lambda = p.alpha * p.alpha * (n + p.kappa) - n;
        if !(n + lambda > 0.0 && lambda.is_finite()) {
            return Err(EstimatorError::NotPositiveSemiDefinite { what: "unscented scaling n + λ" });
        }
        let w = 1.0 / (2.0 * (n + lambda));
        let mut wm = vec![w; 2 * n_tilde + 1];
        let mut wc = wm.clone();
        wm[0] = lambda / (n + lambda);
        wc[0] = lambda / (n + lambda) + (1.0 - p.alpha * p.alpha + p.beta);
        Ok(UtWeights { lambda, spread: (n + lambda).sqrt(), wm, wc })
    }
}

/// A matrix square root `S` with `S S^T = P` for a symmetric positive
/// semi-definite `P`: the lower Cholesky factor, or, when Cholesky fails on a
/// semi-definite matrix, `V sqrt(max(Λ, 0))` from the eigen-decomposition.
/// Fails on non-finite entries or clearly negative eigenvalues.
pub fn sqrt_psd(P: &DMatrix<f64>, what: &'static str) -> Result<DMatrix<f64>, EstimatorError> {
    if !P.iter().all(|v| v.is_finite()) || P.nrows() != P.ncols() {
        return Err(EstimatorError::NotPositiveSemiDefinite { what });
    }
    let sym = (P + P.transpose()) * 0.5;
    if let Some(chol) = sym.clone().cholesky() {
        return Ok(chol.l());
    }
    let eigen = SymmetricEigen::new(sym);
    let scale = eigen.eigenvalues.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    if eigen.eigenvalues.iter().any(|&v| v < -1e-9 * scale.max(1e-300)) {
        return Err(EstimatorError::NotPositiveSemiDefinite { what });
    }
    let roots = eigen.eigenvalues.map(|v| v.max(0.0).sqrt());
    Ok(&eigen.eigenvectors * DMatrix::from_diagonal(&roots))
}

/// Sigma points of an augmented variable `(x, w)`.
#[derive(Clone, Debug, PartialEq)]
pub struct SigmaPoints<S> {
    /// The state parts `X^(i),x`, `2ñ + 1` of them.
    pub states: Vec<S>,
    /// The noise parts `X^(i),w`.
    pub noises: Vec<DVector<f64>>,
    /// Their weights.
    pub weights: UtWeights,
}

/// The sigma points of the augmented variable `(x, w)` with `x ~ belief` and
/// `w ~ N(0, noise_cov)` independent (2.36)/(2.41). The block-diagonal `P̃`
/// has the block-diagonal root `diag(sqrt(P), sqrt(Q))`, so each point moves
/// either the state (through `⊕`) or the noise.
pub fn augmented_sigma_points<S: Manifold>(
    belief: &Belief<S>,
    noise_cov: &DMatrix<f64>,
    params: &UtParams,
) -> Result<SigmaPoints<S>, EstimatorError> {
    let n = belief.mean.dof();
    let n_w = noise_cov.nrows();
    let weights = UtWeights::new(n + n_w, params)?;
    let sqrt_P = sqrt_psd(&belief.cov, "state covariance")?;
    let sqrt_Q = if n_w > 0 { sqrt_psd(noise_cov, "noise covariance")? } else { DMatrix::zeros(0, 0) };
    let c = weights.spread;
    let zero_w = DVector::zeros(n_w);
    let mut xs = Vec::with_capacity(2 * (n + n_w) + 1);
    let mut ws = Vec::with_capacity(2 * (n + n_w) + 1);
    xs.push(belief.mean.clone());
    ws.push(zero_w.clone());
    // Points i = 1..ñ use +column i, points i + ñ use -column i (2.41).
    let mut plus = Vec::with_capacity(n + n_w);
    let mut minus = Vec::with_capacity(n + n_w);
    for i in 0..n {
        let col: Vec<f64> = sqrt_P.column(i).iter().map(|v| c * v).collect();
        let neg: Vec<f64> = col.iter().map(|v| -v).collect();
        plus.push((belief.mean.oplus(&col), zero_w.clone()));
        minus.push((belief.mean.oplus(&neg), zero_w.clone()));
    }
    for i in 0..n_w {
        let col = sqrt_Q.column(i) * c;
        plus.push((belief.mean.clone(), col.clone_owned()));
        minus.push((belief.mean.clone(), -col));
    }
    for (x, w) in plus.into_iter().chain(minus) {
        xs.push(x);
        ws.push(w);
    }
    Ok(SigmaPoints { states: xs, noises: ws, weights })
}

/// The weighted mean and the covariance `Σ W^(c) (Y_i ⊖ μ)(Y_i ⊖ μ)^T` of
/// propagated sigma points, and their deviations `Y_i ⊖ μ` (as columns).
pub fn sigma_mean_cov<S: Manifold>(
    points: &[S],
    weights: &UtWeights,
    what: &'static str,
) -> Result<(S, DMatrix<f64>, DMatrix<f64>), EstimatorError> {
    let mean = S::weighted_mean(points, &weights.wm).ok_or(EstimatorError::NonFiniteState { what })?;
    if !mean.is_finite() {
        return Err(EstimatorError::NonFiniteState { what });
    }
    let n = mean.dof();
    let mut deviations = DMatrix::zeros(n, points.len());
    for (i, p) in points.iter().enumerate() {
        deviations.set_column(i, &p.ominus(&mean));
    }
    let mut cov = DMatrix::zeros(n, n);
    for (i, wc) in weights.wc.iter().enumerate() {
        let d = deviations.column(i);
        cov.ger(*wc, &d, &d, 1.0);
    }
    Ok((mean, cov, deviations))
}

/// UKF prediction (Algorithm 5, (2.41)-(2.43)) for `x_t = f(x_{t-1}, w_{t-1})`,
/// `w ~ N(0, Q)`. `f` receives a state sigma point and a noise sample.
pub fn predict<S, F>(
    belief: &Belief<S>,
    Q: &DMatrix<f64>,
    mut f: F,
    params: &UtParams,
) -> Result<Belief<S>, EstimatorError>
where
    S: Manifold,
    F: FnMut(&S, &DVector<f64>) -> S,
{
    let SigmaPoints { states: xs, noises: ws, weights } = augmented_sigma_points(belief, Q, params)?;
    let propagated: Vec<S> = xs.iter().zip(&ws).map(|(x, w)| f(x, w)).collect(); // (2.42)
    let (mean, cov, _) = sigma_mean_cov(&propagated, &weights, "predicted mean")?; // (2.43)
    let predicted = Belief { mean, cov: symmetrize(cov) };
    predicted.check("predicted belief")?;
    Ok(predicted)
}

/// UKF prediction for additive process noise, `x_t = f(x_{t-1}) + w`: the
/// sigma points of `x` alone (`2n + 1`), then `P^- = Σ W^(c)(...)(...)^T + Q`.
/// For a linear `f` this is exactly the Kalman prediction `F P F^T + Q`.
pub fn predict_additive<S, F>(
    belief: &Belief<S>,
    Q: &DMatrix<f64>,
    mut f: F,
    params: &UtParams,
) -> Result<Belief<S>, EstimatorError>
where
    S: Manifold,
    F: FnMut(&S) -> S,
{
    let none = DMatrix::zeros(0, 0);
    let SigmaPoints { states: xs, weights, .. } = augmented_sigma_points(belief, &none, params)?;
    let propagated: Vec<S> = xs.iter().map(&mut f).collect();
    let (mean, cov, _) = sigma_mean_cov(&propagated, &weights, "predicted mean")?;
    if Q.nrows() != cov.nrows() {
        return Err(EstimatorError::DimensionMismatch { what: "Q", expected: cov.nrows(), got: Q.nrows() });
    }
    let predicted = Belief { mean, cov: symmetrize(cov + Q) };
    predicted.check("predicted belief")?;
    Ok(predicted)
}

/// What a correction did, for gating and diagnostics.
#[derive(Clone, Debug, PartialEq)]
pub struct Correction<S> {
    /// The filtering belief.
    pub posterior: Belief<S>,
    /// `e = z ⊖ μ_z`.
    pub innovation: DVector<f64>,
    /// `P_z`.
    pub innovation_cov: DMatrix<f64>,
    /// `e^T P_z^-1 e`.
    pub mahalanobis2: f64,
}

/// UKF correction (Algorithm 5, (2.44)-(2.46)) with measurement
/// `z = h(x, ν)`, `ν ~ N(0, R)`; `h` receives a state sigma point and a noise
/// sample. The measurement may live on a manifold (`e = z ⊖ μ_z`, Algorithm 9).
pub fn correct<S, Z, H>(
    prior: &Belief<S>,
    z: &Z,
    R: &DMatrix<f64>,
    mut h: H,
    params: &UtParams,
) -> Result<Correction<S>, EstimatorError>
where
    S: Manifold,
    Z: Manifold,
    H: FnMut(&S, &DVector<f64>) -> Z,
{
    if !z.is_finite() {
        return Err(EstimatorError::NonFiniteMeasurement);
    }
    let SigmaPoints { states: xs, noises: nus, weights } = augmented_sigma_points(prior, R, params)?; // (2.44)
    let zs: Vec<Z> = xs.iter().zip(&nus).map(|(x, nu)| h(x, nu)).collect(); // (2.45)
    let (mu_z, P_z, z_dev) = sigma_mean_cov(&zs, &weights, "predicted measurement")?;
    let n = prior.mean.dof();
    let mut P_xz = DMatrix::zeros(n, mu_z.dof());
    for (i, x) in xs.iter().enumerate() {
        let dx = x.ominus(&prior.mean);
        P_xz.ger(weights.wc[i], &dx, &z_dev.column(i), 1.0);
    }
    let e = z.ominus(&mu_z);
    let P_z = symmetrize(P_z);
    let chol = P_z.clone().cholesky().ok_or(EstimatorError::SingularInnovation)?;
    let K = chol.solve(&P_xz.transpose()).transpose(); // K = P_xz P_z^-1
    let mahalanobis2 = e.dot(&chol.solve(&e));
    let step = &K * &e;
    let mean = prior.mean.oplus(step.as_slice()); // μ = μ^- ⊕ K e
    let cov = symmetrize(&prior.cov - &K * &P_z * K.transpose());
    let posterior = Belief { mean, cov };
    posterior.check("corrected belief")?;
    Ok(Correction { posterior, innovation: e, innovation_cov: P_z, mahalanobis2 })
}

/// `(P + P^T) / 2`.
pub fn symmetrize(P: DMatrix<f64>) -> DMatrix<f64> {
    (&P + P.transpose()) * 0.5
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kf::{self, CovarianceUpdate, Gaussian};
    use approx::assert_relative_eq;
    use nalgebra::{SMatrix, SVector};

    #[test]
    fn weights_sum_to_one_and_match_the_formulas() {
        let w = UtWeights::new(3, &UtParams { alpha: 0.5, beta: 2.0, kappa: 1.0 }).unwrap();
        assert_relative_eq!(w.lambda, 0.25 * 4.0 - 3.0, epsilon = 1e-15);
        assert_relative_eq!(w.wm.iter().sum::<f64>(), 1.0, epsilon = 1e-12);
        assert_relative_eq!(w.wc[0], w.wm[0] + 1.0 - 0.25 + 2.0, epsilon = 1e-12);
        assert!(UtWeights::new(3, &UtParams { alpha: 0.0, beta: 2.0, kappa: 0.0 }).is_err());
    }

    #[test]
    fn the_square_root_handles_semi_definite_matrices() {
        let P = DMatrix::from_row_slice(2, 2, &[1.0, 1.0, 1.0, 1.0]);
        let S = sqrt_psd(&P, "test").unwrap();
        assert_relative_eq!(&S * S.transpose(), P, epsilon = 1e-12);
        let bad = DMatrix::from_row_slice(2, 2, &[1.0, 0.0, 0.0, -1.0]);
        assert!(sqrt_psd(&bad, "test").is_err());
        assert!(sqrt_psd(&DMatrix::from_element(1, 1, f64::NAN), "test").is_err());
    }

    /// On a linear-Gaussian system the UKF is exact: it equals the KF.
    #[test]
    #[rustfmt::skip]
    fn on_a_linear_system_the_ukf_equals_the_kalman_filter() {
        let F = SMatrix::<f64, 3, 3>::new(
            1.0, 0.1, 0.0,
            0.0, 1.0, 0.1,
            0.0, 0.0, 0.9,
        );
        let Q = SMatrix::<f64, 3, 3>::from_diagonal(&SVector::<f64, 3>::new(0.01, 0.02, 0.03));
        let H = SMatrix::<f64, 2, 3>::new(
            1.0, 0.0, 0.5,
            0.0, 2.0, 0.0,
        );
        let R = SMatrix::<f64, 2, 2>::new(0.5, 0.1, 0.1, 0.3);
        let mut kf_belief = Gaussian::new(SVector::<f64, 3>::new(1.0, -1.0, 0.5), SMatrix::<f64, 3, 3>::identity());
        let mut ukf_belief = Belief::new(
            DVector::from_column_slice(kf_belief.mean.as_slice()),
            DMatrix::from_column_slice(3, 3, kf_belief.cov.as_slice()),
        ).unwrap();
        let (Fd, Qd, Hd, Rd) = (
            DMatrix::from_column_slice(3, 3, F.as_slice()),
            DMatrix::from_column_slice(3, 3, Q.as_slice()),
            DMatrix::from_column_slice(2, 3, H.as_slice()),
            DMatrix::from_column_slice(2, 2, R.as_slice()),
        );
        for k in 0..5 {
            let z = SVector::<f64, 2>::new(0.3 * k as f64, -0.2 + 0.1 * k as f64);
            kf_belief = kf::predict(&kf_belief, &F, &Q);
            kf_belief = kf::update(&kf_belief, &z, &H, &R, CovarianceUpdate::Simple).unwrap().0;
            let previous = ukf_belief.clone();
            for params in [UtParams::default(), UtParams { alpha: 0.8, beta: 2.0, kappa: 0.5 }] {
                let p = predict(&previous, &Qd, |x, w| &Fd * x + w, &params).unwrap();
                let zd = DVector::from_column_slice(z.as_slice());
                let c = correct(&p, &zd, &Rd, |x, nu| &Hd * x + nu, &params).unwrap();
                assert_relative_eq!(c.posterior.mean.as_slice(), kf_belief.mean.as_slice(), epsilon = 1e-9);
                assert_relative_eq!(c.posterior.cov.as_slice(), kf_belief.cov.as_slice(), epsilon = 1e-9);
                ukf_belief = c.posterior;
            }
        }
    }

    #[test]
    fn additive_prediction_of_a_linear_model_is_the_kalman_prediction() {
        let F = DMatrix::from_row_slice(2, 2, &[1.0, 0.5, 0.0, 1.0]);
        let Q = DMatrix::from_row_slice(2, 2, &[0.1, 0.0, 0.0, 0.2]);
        let b = Belief::new(
            DVector::from_vec(vec![1.0, 2.0]),
            DMatrix::from_row_slice(2, 2, &[1.0, 0.3, 0.3, 2.0]),
        )
        .unwrap();
        let p = predict_additive(&b, &Q, |x| &F * x, &UtParams::default()).unwrap();
        assert_relative_eq!(p.mean, &F * &b.mean, epsilon = 1e-12);
        assert_relative_eq!(p.cov, &F * &b.cov * F.transpose() + &Q, epsilon = 1e-12);
    }

    /// A nonlinear case with a closed form: for `z = x^2` with `x ~ N(m, s²)`
    /// the unscented transform (κ chosen so that ñ + λ = 3) gives the exact mean
    /// `m² + s²` and variance `4 m² s² + 2 s⁴`.
    #[test]
    fn the_unscented_transform_of_a_square_is_exact_for_gaussians() {
        let (m, s2) = (1.5, 0.4);
        let b = Belief::new(DVector::from_vec(vec![m]), DMatrix::from_element(1, 1, s2)).unwrap();
        let params = UtParams { alpha: 1.0, beta: 2.0, kappa: 2.0 };
        let SigmaPoints { states: xs, weights: w, .. } =
            augmented_sigma_points(&b, &DMatrix::zeros(0, 0), &params).unwrap();
        let zs: Vec<DVector<f64>> = xs.iter().map(|x| x.map(|v| v * v)).collect();
        // With β = 2 the centre covariance weight differs from the mean weight;
        // use the mean weights for the variance check of the exact moments.
        let mean: f64 = zs.iter().zip(&w.wm).map(|(z, w)| w * z[0]).sum();
        let var: f64 = zs.iter().zip(&w.wm).map(|(z, w)| w * (z[0] - mean).powi(2)).sum();
        assert_relative_eq!(mean, m * m + s2, epsilon = 1e-12);
        assert_relative_eq!(var, 4.0 * m * m * s2 + 2.0 * s2 * s2, epsilon = 1e-12);
    }

    #[test]
    fn a_non_finite_measurement_is_refused() {
        let b = Belief::new(DVector::from_vec(vec![0.0]), DMatrix::identity(1, 1)).unwrap();
        let z = DVector::from_vec(vec![f64::NAN]);
        let r = correct(&b, &z, &DMatrix::identity(1, 1), |x, nu| x + nu, &UtParams::default());
        assert_eq!(r.unwrap_err(), EstimatorError::NonFiniteMeasurement);
    }
}
