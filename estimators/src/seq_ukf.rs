//! The Unscented Kalman correction for additive measurement noise in
//! statistical-Jacobian form (thesis (2.62)-(2.67)) and its sequential version
//! (Algorithm 7, after McManus and Barfoot), for high-dimensional measurements
//! `z = h(x) + ν`, `ν ~ N(0, R)` with block-diagonal `R`.
//!
//! With `𝒳 = [sqrt(W_i^(c)) (X_i ⊖ μ^-)]` and `𝒵 = [sqrt(W_i^(c)) (Z_i - μ_z)]`
//! (2.63)-(2.64), the batch correction is (2.67)
//! `μ = μ^- ⊕ 𝒳 𝒵^T P_z^-1 (z - μ_z)`, `P = 𝒳 𝒳^T - 𝒳 𝒵^T P_z^-1 𝒵 𝒳^T`,
//! `P_z = 𝒵 𝒵^T + R`, which inverts an `m x m` matrix. The Sherman-Morrison-
//! Woodbury identities (2.73)-(2.74) turn it into (2.76)-(2.80):
//! `μ = μ^- ⊕ 𝒳 𝒞 d`, `P = 𝒳 𝒞 𝒳^T`, with `𝒞^-1 = I + Σ_j 𝒵_j^T R_j^-1 𝒵_j` and
//! `d = Σ_j 𝒵_j^T R_j^-1 (z_j - μ_z,j)` accumulated block by block, which only
//! inverts a `(2n+1) x (2n+1)` matrix. Both give the same result (a test
//! checks it to 1e-9).
//!
//! Sigma points: drawn from the predicted belief `(μ^-, P^-)` with `n` points
//! per side, so that `𝒳 𝒳^T = P^-` holds exactly, which (2.75) relies on. (The
//! thesis reuses the propagated points (2.81); drawing them afresh is the same
//! when the prediction has no separate additive noise, and stays exact when it
//! does.) Note (2.87) prints `P_t = P_t^- + 𝒳 𝒞 𝒳^T`; the derivation (2.75)-(2.76)
//! gives `P_t = 𝒳 𝒞 𝒳^T`, which is what is implemented.
#![expect(non_snake_case, reason = "matrices are named as in the thesis's equations (F, H, Q, R, P, K)")]

use nalgebra::{DMatrix, DVector};

use crate::EstimatorError;
use crate::ukf::{Belief, Manifold, SigmaPoints, UtParams, augmented_sigma_points, symmetrize};

/// The statistical Jacobians of one correction step: (2.83).
#[derive(Clone, Debug, PartialEq)]
pub struct StatisticalJacobians<S> {
    /// The sigma points `X_i` (drawn from the prior), `2n + 1`.
    pub sigma_points: Vec<S>,
    /// `𝒳`, `n x (2n+1)`.
    pub X: DMatrix<f64>,
    /// `𝒵`, `m x (2n+1)`.
    pub Z: DMatrix<f64>,
    /// `μ_z = Σ W_i^(m) Z_i`, `m` entries.
    pub mu_z: DVector<f64>,
}

impl<S: Manifold> StatisticalJacobians<S> {
    /// Draws the sigma points of `prior`, evaluates the measurement function on
    /// all of them at once (`h_all` returns the `m x (2n+1)` matrix whose
    /// column `i` is `h(X_i)`) and forms `𝒳`, `𝒵` and `μ_z`.
    pub fn new<H>(
        prior: &Belief<S>,
        params: &UtParams,
        h_all: H,
    ) -> Result<StatisticalJacobians<S>, EstimatorError>
    where
        H: FnOnce(&[S]) -> DMatrix<f64>,
    {
        let none = DMatrix::zeros(0, 0);
        let SigmaPoints { states: sigma_points, weights, .. } = augmented_sigma_points(prior, &none, params)?; // (2.81)
        if weights.wc.iter().any(|w| *w < 0.0) {
            return Err(EstimatorError::NotPositiveSemiDefinite { what: "covariance weights W^(c)" });
        }
        let count = sigma_points.len();
        let mut Z = h_all(&sigma_points); // (2.82)
        if Z.ncols() != count {
            return Err(EstimatorError::DimensionMismatch {
                what: "measurement sigma points",
                expected: count,
                got: Z.ncols(),
            });
        }
        if !Z.iter().all(|v| v.is_finite()) {
            return Err(EstimatorError::NonFiniteState { what: "predicted measurement" });
        }
        let mut mu_z = DVector::zeros(Z.nrows());
        for (i, w) in weights.wm.iter().enumerate() {
            mu_z.axpy(*w, &Z.column(i), 1.0);
        }
        let n = prior.mean.dof();
        let mut X = DMatrix::zeros(n, count);
        for (i, x) in sigma_points.iter().enumerate() {
            let s = weights.wc[i].sqrt();
            X.set_column(i, &(x.ominus(&prior.mean) * s));
            let mut column = Z.column_mut(i);
            column -= &mu_z;
            column *= s;
        }
        Ok(StatisticalJacobians { sigma_points, X, Z, mu_z })
    }
}

/// The block-diagonal measurement covariance `R = diag(R_1, ..., R_M)` (2.51).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum BlockNoise<'a> {
    /// `R_j = σ_j² I` for blocks of `block_size` rows: one variance per block.
    Isotropic {
        /// Rows per block `m̃`.
        block_size: usize,
        /// `σ_j²`, one per block.
        variances: &'a [f64],
    },
    /// Full blocks `R_j` (each square, all the same size).
    Blocks(&'a [DMatrix<f64>]),
}

impl BlockNoise<'_> {
    /// Total measurement size `m`.
    pub fn rows(&self) -> usize {
        match self {
            BlockNoise::Isotropic { block_size, variances } => block_size * variances.len(),
            BlockNoise::Blocks(blocks) => blocks.iter().map(|b| b.nrows()).sum(),
        }
    }

    /// The full `m x m` matrix (for the batch form and tests).
    pub fn dense(&self) -> DMatrix<f64> {
        let m = self.rows();
        let mut R = DMatrix::zeros(m, m);
        let mut offset = 0;
        match self {
            BlockNoise::Isotropic { block_size, variances } => {
                for v in *variances {
                    for k in 0..*block_size {
                        R[(offset + k, offset + k)] = *v;
                    }
                    offset += block_size;
                }
            }
            BlockNoise::Blocks(blocks) => {
                for b in *blocks {
                    R.view_mut((offset, offset), (b.nrows(), b.ncols())).copy_from(b);
                    offset += b.nrows();
                }
            }
        }
        R
    }
}

/// The batch correction in statistical-Jacobian form (2.67): inverts the
/// `m x m` matrix `P_z = 𝒵 𝒵^T + R`. The reference the sequential form is
/// checked against; too slow for point clouds.
pub fn correct_batch<S: Manifold>(
    prior: &Belief<S>,
    jacobians: &StatisticalJacobians<S>,
    z: &DVector<f64>,
    R: &DMatrix<f64>,
) -> Result<Belief<S>, EstimatorError> {
    let StatisticalJacobians { X, Z, mu_z, .. } = jacobians;
    check_measurement(z, mu_z.len())?;
    let P_z = symmetrize(Z * Z.transpose() + R);
    let chol = P_z.cholesky().ok_or(EstimatorError::SingularInnovation)?;
    let gain_input = chol.solve(&(z - mu_z)); // P_z^-1 (z - μ_z)
    let step = X * (Z.transpose() * gain_input);
    let mean = prior.mean.oplus(step.as_slice());
    let ZX = Z * X.transpose(); // 𝒵 𝒳^T
    let cov = symmetrize(X * X.transpose() - ZX.transpose() * chol.solve(&ZX));
    let posterior = Belief { mean, cov };
    posterior.check("corrected belief")?;
    Ok(posterior)
}

/// The sequential correction (Algorithm 7, steps 4-6): accumulates `d` and
/// `𝒞^-1` over the blocks (2.84)-(2.86), then `μ = μ^- ⊕ 𝒳 𝒞 d`,
/// `P = 𝒳 𝒞 𝒳^T`. For isotropic blocks the sum `Σ_j 𝒵_j^T R_j^-1 𝒵_j` is
/// evaluated as one product of the row-scaled `𝒵` with itself (the same sum,
/// computed faster).
pub fn correct_sequential<S: Manifold>(
    prior: &Belief<S>,
    jacobians: &StatisticalJacobians<S>,
    z: &DVector<f64>,
    noise: BlockNoise<'_>,
) -> Result<Belief<S>, EstimatorError> {
    let StatisticalJacobians { X, Z, mu_z, .. } = jacobians;
    check_measurement(z, mu_z.len())?;
    if noise.rows() != z.len() {
        return Err(EstimatorError::DimensionMismatch { what: "R", expected: z.len(), got: noise.rows() });
    }
    let count = Z.ncols();
    let mut C_inv = DMatrix::<f64>::identity(count, count); // (2.84)
    let mut d = DVector::<f64>::zeros(count);
    match noise {
        BlockNoise::Isotropic { block_size, variances } => {
            // Rows of block j scaled by 1/σ_j: Σ_j 𝒵_j^T 𝒵_j / σ_j² = Ẑ^T Ẑ.
            let mut Z_scaled = Z.clone();
            let mut e = z - mu_z;
            for (j, v) in variances.iter().enumerate() {
                if !(*v > 0.0 && v.is_finite()) {
                    return Err(EstimatorError::NotPositiveSemiDefinite { what: "measurement variance" });
                }
                let s = 1.0 / v.sqrt();
                Z_scaled.rows_mut(j * block_size, block_size).scale_mut(s);
                e.rows_mut(j * block_size, block_size).scale_mut(s);
            }
            C_inv.gemm_tr(1.0, &Z_scaled, &Z_scaled, 1.0); // (2.85), all j at once
            d.gemv_tr(1.0, &Z_scaled, &e, 0.0);
        }
        BlockNoise::Blocks(blocks) => {
            let mut offset = 0;
            for R_j in blocks {
                let m = R_j.nrows();
                let R_j_inv = R_j.clone().try_inverse().ok_or(EstimatorError::SingularInnovation)?;
                let Z_j = Z.rows(offset, m);
                let e_j = z.rows(offset, m) - mu_z.rows(offset, m);
                let Zt_Rinv = Z_j.transpose() * R_j_inv;
                d += &Zt_Rinv * e_j; // (2.85)
                C_inv += &Zt_Rinv * Z_j;
                offset += m;
            }
        }
    }
    let chol = symmetrize(C_inv).cholesky().ok_or(EstimatorError::SingularInnovation)?;
    let C = chol.inverse(); // (2.88)
    let step = X * (&C * d); // 𝒳 𝒞 d
    let mean = prior.mean.oplus(step.as_slice());
    let cov = symmetrize(X * &C * X.transpose()); // (2.76)
    let posterior = Belief { mean, cov };
    posterior.check("corrected belief")?;
    Ok(posterior)
}

fn check_measurement(z: &DVector<f64>, expected: usize) -> Result<(), EstimatorError> {
    if z.len() != expected {
        return Err(EstimatorError::DimensionMismatch { what: "measurement", expected, got: z.len() });
    }
    if !z.iter().all(|v| v.is_finite()) {
        return Err(EstimatorError::NonFiniteMeasurement);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::orientation::{Component, Composite, put_quaternion};
    use crate::ukf::correct;
    use approx::assert_relative_eq;
    use nalgebra::{UnitQuaternion, Vector3};

    /// A nonlinear measurement of a 4-state: 30 points, 3 coordinates each.
    fn h(x: &DVector<f64>) -> DVector<f64> {
        DVector::from_fn(90, |r, _| {
            let j = (r / 3) as f64;
            match r % 3 {
                0 => x[0] + x[1] * j.sin() + 0.1 * x[2] * x[2],
                1 => (x[1] * 0.3 + x[3] * j.cos()).sin(),
                _ => x[0] * x[3] + 0.05 * j * x[2],
            }
        })
    }

    fn h_all(points: &[DVector<f64>]) -> DMatrix<f64> {
        let mut Z = DMatrix::zeros(90, points.len());
        for (i, p) in points.iter().enumerate() {
            Z.set_column(i, &h(p));
        }
        Z
    }

    fn prior() -> Belief<DVector<f64>> {
        let mean = DVector::from_vec(vec![0.3, -0.2, 0.8, 0.1]);
        let A = DMatrix::from_fn(4, 4, |r, c| {
            ((r * 7 + c * 3) % 5) as f64 * 0.05 + if r == c { 0.2 } else { 0.0 }
        });
        Belief::new(mean, &A * A.transpose()).unwrap()
    }

    fn measurement() -> DVector<f64> {
        DVector::from_fn(90, |r, _| 0.4 * ((r as f64) * 0.7).sin())
    }

    #[test]
    fn sequential_equals_batch_for_isotropic_and_full_blocks() {
        let prior = prior();
        let params = UtParams::default();
        let jac = StatisticalJacobians::new(&prior, &params, h_all).unwrap();
        let z = measurement();
        let variances: Vec<f64> = (0..30).map(|j| 0.01 + 0.002 * j as f64).collect();
        let iso = BlockNoise::Isotropic { block_size: 3, variances: &variances };
        let batch = correct_batch(&prior, &jac, &z, &iso.dense()).unwrap();
        let seq = correct_sequential(&prior, &jac, &z, iso).unwrap();
        assert_relative_eq!(seq.mean, batch.mean, epsilon = 1e-9);
        assert_relative_eq!(seq.cov, batch.cov, epsilon = 1e-9);

        let blocks: Vec<DMatrix<f64>> = (0..30)
            .map(|j| {
                let a = 0.01 + 0.001 * j as f64;
                DMatrix::from_row_slice(3, 3, &[a, 0.002, 0.0, 0.002, a, 0.001, 0.0, 0.001, 2.0 * a])
            })
            .collect();
        let full = BlockNoise::Blocks(&blocks);
        let batch = correct_batch(&prior, &jac, &z, &full.dense()).unwrap();
        let seq = correct_sequential(&prior, &jac, &z, full).unwrap();
        assert_relative_eq!(seq.mean, batch.mean, epsilon = 1e-9);
        assert_relative_eq!(seq.cov, batch.cov, epsilon = 1e-9);
    }

    /// The statistical-Jacobian batch form is the UKF correction of
    /// Algorithm 5 for additive noise: both evaluate the same sigma points.
    #[test]
    fn the_batch_form_is_the_additive_ukf_correction() {
        let prior = prior();
        let params = UtParams::default();
        let jac = StatisticalJacobians::new(&prior, &params, h_all).unwrap();
        let z = measurement();
        let R = DMatrix::from_diagonal_element(90, 90, 0.02);
        let batch = correct_batch(&prior, &jac, &z, &R).unwrap();
        // Algorithm 5 with h(x, ν) = h(x) + ν and ñ = n + m would use other
        // weights; with the additive-noise recipe (2.62) the reference is:
        let (mu_z, Z, X) = (&jac.mu_z, &jac.Z, &jac.X);
        let P_z = Z * Z.transpose() + &R;
        let P_xz = X * Z.transpose();
        let K = &P_xz * P_z.clone().try_inverse().unwrap();
        let mean = &prior.mean + &K * (&z - mu_z);
        let cov = &prior.cov - &K * &P_z * K.transpose();
        assert_relative_eq!(batch.mean, mean, epsilon = 1e-9);
        assert_relative_eq!(batch.cov, cov, epsilon = 1e-9);
        // ... and 𝒳 𝒳^T reproduces the prior covariance exactly.
        assert_relative_eq!(X * X.transpose(), prior.cov, epsilon = 1e-12);
        // A linear measurement gives the Kalman update through `correct` too.
        let H = DMatrix::from_fn(6, 4, |r, c| ((r + 2 * c) % 3) as f64 - 0.5);
        let z6 = DVector::from_fn(6, |r, _| r as f64 * 0.1);
        let R6 = DMatrix::from_diagonal_element(6, 6, 0.1);
        let jac6 = StatisticalJacobians::new(&prior, &params, |xs| {
            DMatrix::from_columns(&xs.iter().map(|x| &H * x).collect::<Vec<_>>())
        })
        .unwrap();
        let seq = correct_sequential(
            &prior,
            &jac6,
            &z6,
            BlockNoise::Isotropic { block_size: 2, variances: &[0.1; 3] },
        )
        .unwrap();
        let ukf = correct(&prior, &z6, &R6, |x, nu| &H * x + nu, &params).unwrap().posterior;
        assert_relative_eq!(seq.mean, ukf.mean, epsilon = 1e-9);
        assert_relative_eq!(seq.cov, ukf.cov, epsilon = 1e-9);
    }

    /// The same identity on a composite state with Euler angles and a
    /// quaternion: the sequential and batch forms share `⊕` and `𝒳`.
    #[test]
    fn sequential_equals_batch_on_a_composite_state() {
        const LAYOUT: &[Component] = &[Component::Euclidean(3), Component::Angles(3), Component::Quaternion];
        let mut coords = DVector::zeros(10);
        coords.rows_mut(0, 3).copy_from_slice(&[0.1, 0.2, 0.5]);
        coords.rows_mut(3, 3).copy_from_slice(&[3.0, -0.4, 0.2]);
        put_quaternion(&mut coords, 6, &UnitQuaternion::from_scaled_axis(Vector3::new(0.3, -0.2, 1.0)));
        let mean = Composite::new(LAYOUT, coords).unwrap();
        let prior = Belief::new(mean, DMatrix::from_diagonal_element(9, 9, 0.01)).unwrap();
        let h_point = |x: &Composite, j: usize| -> Vector3<f64> {
            let q = x.quaternion_at(6);
            let a = Vector3::new(j as f64 * 0.01, (j as f64).sin() * 0.05, 0.02);
            q * a + x.vector3_at(0) + x.vector3_at(3) * 0.01
        };
        let jac = StatisticalJacobians::new(&prior, &UtParams::default(), |xs| {
            DMatrix::from_fn(60, xs.len(), |r, i| h_point(&xs[i], r / 3)[r % 3])
        })
        .unwrap();
        let z = DVector::from_fn(60, |r, _| 0.3 + 0.01 * r as f64);
        let variances = [0.001; 20];
        let noise = BlockNoise::Isotropic { block_size: 3, variances: &variances };
        let batch = correct_batch(&prior, &jac, &z, &noise.dense()).unwrap();
        let seq = correct_sequential(&prior, &jac, &z, noise).unwrap();
        assert_relative_eq!(seq.mean.coords(), batch.mean.coords(), epsilon = 1e-9);
        assert_relative_eq!(seq.cov, batch.cov, epsilon = 1e-9);
    }

    #[test]
    fn bad_measurements_are_refused() {
        let prior = prior();
        let jac = StatisticalJacobians::new(&prior, &UtParams::default(), h_all).unwrap();
        let mut z = measurement();
        z[5] = f64::NAN;
        let noise = BlockNoise::Isotropic { block_size: 3, variances: &[0.01; 30] };
        assert_eq!(correct_sequential(&prior, &jac, &z, noise), Err(EstimatorError::NonFiniteMeasurement));
        let short = DVector::zeros(3);
        assert!(correct_sequential(&prior, &jac, &short, noise).is_err());
        let bad_noise = BlockNoise::Isotropic { block_size: 3, variances: &[0.0; 30] };
        assert!(correct_sequential(&prior, &jac, &measurement(), bad_noise).is_err());
    }
}
