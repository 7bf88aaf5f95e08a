//! The sequential Kalman correction (thesis Algorithm 6): a measurement made
//! of `M` uncorrelated blocks `z_j` of `B` rows, `R = diag(R_1, ..., R_M)`
//! (2.50)-(2.51), is processed one block at a time (2.56)-(2.59), inverting
//! `B x B` matrices only. For linear measurements `z_j = H_j x + ν_j` the
//! result equals the batch Kalman update; for nonlinear ones `h_j` is
//! evaluated at the running iterate `μ_{j-1}` and `H_j` is the Jacobian at
//! the prior mean (2.58), as in the EKF. The prediction is the ordinary one
//! ([`crate::kf::predict`]).
#![expect(non_snake_case, reason = "matrices are named as in the thesis's equations (F, H, Q, R, P, K)")]

use nalgebra::{SMatrix, SVector};

use crate::EstimatorError;
use crate::kf::Gaussian;

/// One block of a linear measurement: `z_j = H_j x + ν_j`, `ν_j ~ N(0, R_j)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LinearBlock<const N: usize, const B: usize> {
    /// `z_j`.
    pub z: SVector<f64, B>,
    /// `H_j`, `B x N`.
    pub H: SMatrix<f64, B, N>,
    /// `R_j`, `B x B`.
    pub R: SMatrix<f64, B, B>,
}

/// One block as the nonlinear form needs it: the predicted block
/// `h_j = h(μ_{j-1})` evaluated by the caller at the running iterate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Block<const N: usize, const B: usize> {
    /// `z_j`.
    pub z: SVector<f64, B>,
    /// `h_j` (2.58).
    pub h: SVector<f64, B>,
    /// `H_{x,j}` (2.58).
    pub H: SMatrix<f64, B, N>,
    /// `R_j`.
    pub R: SMatrix<f64, B, B>,
}

/// What a sequential correction did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SequentialStats {
    /// Blocks used.
    pub used: usize,
    /// Blocks skipped because `z_j` was not finite or `P_z,j` was singular.
    pub skipped: usize,
}

/// Sequential correction with linear blocks (Algorithm 6 with `h_j = H_j μ_{j-1}`).
pub fn correct_linear<const N: usize, const B: usize>(
    prior: &Gaussian<N>,
    blocks: impl IntoIterator<Item = LinearBlock<N, B>>,
) -> Result<(Gaussian<N>, SequentialStats), EstimatorError> {
    let mut blocks = blocks.into_iter();
    correct(prior, |mu| blocks.next().map(|b| Block { z: b.z, h: b.H * mu, H: b.H, R: b.R }))
}

/// Sequential correction (Algorithm 6, (2.56)-(2.59)). `next_block` is called
/// with the running iterate `μ_{j-1}` and returns block `j`, or `None` after
/// the last one. A block whose `z_j` is not finite, or whose `P_z,j` cannot be
/// inverted, is skipped and counted. Fails (leaving the caller's prior
/// untouched) if the result is not finite.
pub fn correct<const N: usize, const B: usize>(
    prior: &Gaussian<N>,
    mut next_block: impl FnMut(&SVector<f64, N>) -> Option<Block<N, B>>,
) -> Result<(Gaussian<N>, SequentialStats), EstimatorError> {
    let mut mu = prior.mean; // (2.56)
    let mut P = prior.cov;
    let mut stats = SequentialStats::default();
    while let Some(block) = next_block(&mu) {
        if !(block.z.iter().all(|v| v.is_finite()) && block.h.iter().all(|v| v.is_finite())) {
            stats.skipped += 1;
            continue;
        }
        let PHt = P * block.H.transpose();
        let P_z = block.H * PHt + block.R; // (2.57)
        let Some(P_z_inv) = P_z.try_inverse() else {
            stats.skipped += 1;
            continue;
        };
        let K = PHt * P_z_inv;
        mu += K * (block.z - block.h);
        P -= K * P_z * K.transpose();
        stats.used += 1;
    }
    let P = (P + P.transpose()) * 0.5;
    let finite = mu.iter().chain(P.iter()).all(|v| v.is_finite()) && P.diagonal().iter().all(|v| *v >= 0.0);
    if !finite {
        return Err(EstimatorError::NonFiniteState { what: "sequential KF belief" });
    }
    Ok((Gaussian::new(mu, P), stats)) // (2.59)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kf::{CovarianceUpdate, update};
    use approx::assert_relative_eq;

    fn blocks() -> Vec<LinearBlock<3, 2>> {
        (0..8)
            .map(|j| {
                let t = j as f64;
                LinearBlock {
                    z: SVector::<f64, 2>::new(t.sin(), 0.5 * t.cos()),
                    H: SMatrix::<f64, 2, 3>::new(1.0, 0.1 * t, 0.0, 0.0, 1.0, -0.2 * t),
                    R: SMatrix::<f64, 2, 2>::new(0.2 + 0.01 * t, 0.05, 0.05, 0.3),
                }
            })
            .collect()
    }

    #[test]
    fn sequential_equals_batch_on_a_linear_measurement() {
        let prior = Gaussian::new(
            SVector::<f64, 3>::new(0.1, -0.3, 0.7),
            SMatrix::<f64, 3, 3>::new(1.0, 0.2, 0.0, 0.2, 0.5, 0.1, 0.0, 0.1, 2.0),
        );
        let bs = blocks();
        let (seq, stats) = correct_linear(&prior, bs.clone()).unwrap();
        assert_eq!(stats, SequentialStats { used: 8, skipped: 0 });
        let mut z = SVector::<f64, 16>::zeros();
        let mut H = SMatrix::<f64, 16, 3>::zeros();
        let mut R = SMatrix::<f64, 16, 16>::zeros();
        for (j, b) in bs.iter().enumerate() {
            z.fixed_rows_mut::<2>(2 * j).copy_from(&b.z);
            H.fixed_rows_mut::<2>(2 * j).copy_from(&b.H);
            R.fixed_view_mut::<2, 2>(2 * j, 2 * j).copy_from(&b.R);
        }
        let (batch, _) = update(&prior, &z, &H, &R, CovarianceUpdate::Simple).unwrap();
        assert_relative_eq!(seq.mean, batch.mean, epsilon = 1e-9);
        assert_relative_eq!(seq.cov, batch.cov, epsilon = 1e-9);
    }

    #[test]
    fn non_finite_blocks_are_skipped() {
        let prior = Gaussian::new(SVector::<f64, 3>::zeros(), SMatrix::<f64, 3, 3>::identity());
        let mut bs = blocks();
        bs[3].z[0] = f64::NAN;
        let (with_nan, stats) = correct_linear(&prior, bs.clone()).unwrap();
        assert_eq!(stats, SequentialStats { used: 7, skipped: 1 });
        bs.remove(3);
        let (without, _) = correct_linear(&prior, bs).unwrap();
        assert_eq!(with_nan, without);
        assert!(with_nan.mean.iter().all(|v| v.is_finite()));
    }

    #[test]
    fn no_blocks_leave_the_prior_unchanged() {
        let prior = Gaussian::new(SVector::<f64, 3>::new(1.0, 2.0, 3.0), SMatrix::<f64, 3, 3>::identity());
        let (post, stats) = correct_linear::<3, 2>(&prior, []).unwrap();
        assert_eq!(post, prior);
        assert_eq!(stats.used, 0);
    }
}
