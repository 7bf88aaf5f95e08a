//! One step of the dEKF's Extended Kalman filter for a state of `M` degrees
//! of freedom, `x = (p, v)` with `N = 2 M` components, and its reverse-mode
//! derivative: the equations of [`crate::dekf::ekf`] (thesis Algorithm 3,
//! eqs. 6.3-6.6) with vectors where the thesis has scalars.
//!
//! Prediction (6.3): `x- = (p + v dt, v + a)`, `a = NN1(x)` (`M` values),
//! `F = [[I, dt I], [J1_p, I + J1_v]]` with `J1 = dNN1/dx` (`M x N`),
//! `P- = F P F^T + Q`. Correction (6.5)-(6.6) with the feature
//! `z = NN3(tau')` and `z^ = NN2(x-)` (`M` values each), `H = dNN2/dx` at
//! `x-`: `S = H P- H^T + R`, `K = P- H^T S^-1`, `x = x- + K (z - z^)`,
//! `P = (I - K H) P- (I - K H)^T + K R K^T` (Joseph form).
//!
//! As in the one-dimensional module, the reverse-mode functions hold the
//! networks' outputs fixed; the caller adds the paths through the networks.
#![expect(non_snake_case, reason = "matrices are named as in the thesis's equations (F, H, Q, R, P, K, S)")]

use nalgebra::{SMatrix, SVector};

/// An `R x C` matrix.
pub type Mat<const R: usize, const C: usize> = SMatrix<f64, R, C>;
/// A vector of `R` components.
pub type Vect<const R: usize> = SVector<f64, R>;

/// The quantities of one prediction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Predicted<const N: usize> {
    /// `x-`.
    pub mean: Vect<N>,
    /// `P-`.
    pub cov: Mat<N, N>,
    /// `F`.
    pub F: Mat<N, N>,
}

/// `F = [[I, dt I], [J1_p, I + J1_v]]`.
fn transition<const N: usize, const M: usize>(J1: &Mat<M, N>, dt: f64) -> Mat<N, N> {
    let mut F = Mat::<N, N>::identity();
    for i in 0..M {
        F[(i, M + i)] = dt;
        for j in 0..N {
            F[(M + i, j)] += J1[(i, j)];
        }
    }
    F
}

/// Prediction from `(mean, cov)` with NN1's output `a` and Jacobian `J1`.
pub fn predict<const N: usize, const M: usize>(
    mean: &Vect<N>,
    cov: &Mat<N, N>,
    a: &Vect<M>,
    J1: &Mat<M, N>,
    dt: f64,
    Q: &Mat<N, N>,
) -> Predicted<N> {
    let F = transition(J1, dt);
    let mut m = *mean;
    for i in 0..M {
        m[i] = mean[i] + mean[M + i] * dt;
        m[M + i] = mean[M + i] + a[i];
    }
    Predicted { mean: m, cov: F * cov * F.transpose() + Q, F }
}

/// Adjoints flowing out of a prediction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PredictGrad<const N: usize, const M: usize> {
    /// d loss / d previous mean with NN1's outputs held fixed.
    pub mean: Vect<N>,
    /// d loss / d previous covariance.
    pub cov: Mat<N, N>,
    /// d loss / d a.
    pub a: Vect<M>,
    /// d loss / d J1.
    pub J1: Mat<M, N>,
    /// d loss / d Q.
    pub Q: Mat<N, N>,
}

/// Reverse of [`predict`] from the adjoints of `x-` and `P-`.
pub fn predict_backward<const N: usize, const M: usize>(
    pred: &Predicted<N>,
    cov: &Mat<N, N>,
    dt: f64,
    dmean: &Vect<N>,
    dcov: &Mat<N, N>,
) -> PredictGrad<N, M> {
    let F = &pred.F;
    // P- = F P F^T + Q: dP = F^T dP- F, dF = dP- F P^T + dP-^T F P.
    let dP = F.transpose() * dcov * F;
    let dF = dcov * F * cov.transpose() + dcov.transpose() * F * cov;
    let mut da = Vect::<M>::zeros();
    let mut dJ1 = Mat::<M, N>::zeros();
    let mut dprev = *dmean;
    for i in 0..M {
        da[i] = dmean[M + i];
        dprev[M + i] = dmean[i] * dt + dmean[M + i];
        for j in 0..N {
            dJ1[(i, j)] = dF[(M + i, j)];
        }
    }
    PredictGrad { mean: dprev, cov: dP, a: da, J1: dJ1, Q: *dcov }
}

/// The quantities of one correction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Corrected<const N: usize, const M: usize> {
    /// `x`.
    pub mean: Vect<N>,
    /// `P`.
    pub cov: Mat<N, N>,
    /// `S^-1`.
    pub S_inv: Mat<M, M>,
    /// `K`.
    pub K: Mat<N, M>,
    /// `z - z^`.
    pub innovation: Vect<M>,
}

/// Correction of the prediction `(mean, cov)` with the feature `z`, NN2's
/// output `zhat` and Jacobian `H` at the predicted mean, and `R`. `None`
/// when `S` is not positive definite (the measurement carries no usable
/// information: the step only predicts).
pub fn correct<const N: usize, const M: usize>(
    mean: &Vect<N>,
    cov: &Mat<N, N>,
    z: &Vect<M>,
    zhat: &Vect<M>,
    H: &Mat<M, N>,
    R: &Mat<M, M>,
) -> Option<Corrected<N, M>> {
    let U = cov * H.transpose();
    let S = H * U + R;
    // S is symmetric positive definite for a usable measurement (the
    // Cholesky factorisation is the test); the inverse is taken in general
    // form so that the adjoints of `correct_backward` are exact even for a
    // perturbation that breaks the symmetry.
    S.cholesky()?;
    let S_inv = S.try_inverse()?;
    let K = U * S_inv;
    let y = z - zhat;
    let A = Mat::<N, N>::identity() - K * H;
    let c = A * cov * A.transpose() + K * R * K.transpose();
    Some(Corrected { mean: mean + K * y, cov: c, S_inv, K, innovation: y })
}

/// Adjoints flowing out of a correction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CorrectGrad<const N: usize, const M: usize> {
    /// d loss / d predicted mean with NN2's outputs held fixed.
    pub mean: Vect<N>,
    /// d loss / d predicted covariance.
    pub cov: Mat<N, N>,
    /// d loss / d z (NN3's output).
    pub z: Vect<M>,
    /// d loss / d zhat (NN2's output).
    pub zhat: Vect<M>,
    /// d loss / d H (NN2's Jacobian).
    pub H: Mat<M, N>,
    /// d loss / d R.
    pub R: Mat<M, M>,
}

impl<const N: usize, const M: usize> CorrectGrad<N, M> {
    /// The adjoints of a step that did not correct: the mean's and the
    /// covariance's pass through, nothing reaches the measurement side.
    pub fn passing(mean: Vect<N>, cov: Mat<N, N>) -> CorrectGrad<N, M> {
        CorrectGrad { mean, cov, z: Vect::zeros(), zhat: Vect::zeros(), H: Mat::zeros(), R: Mat::zeros() }
    }
}

/// Reverse of [`correct`] from the adjoints of `x` and `P`.
pub fn correct_backward<const N: usize, const M: usize>(
    c: &Corrected<N, M>,
    cov: &Mat<N, N>,
    H: &Mat<M, N>,
    R: &Mat<M, M>,
    dmean: &Vect<N>,
    dcov: &Mat<N, N>,
) -> CorrectGrad<N, M> {
    let (K, S_inv, y) = (&c.K, &c.S_inv, &c.innovation);
    let A = Mat::<N, N>::identity() - K * H;
    // Written for general (not necessarily symmetric) P-, R and S, so that
    // the adjoint of every element is exact.
    // P = A P- A^T + K R K^T.
    let dA = dcov * A * cov.transpose() + dcov.transpose() * A * cov;
    let mut dPm = A.transpose() * dcov * A;
    let mut dK = dcov * K * R.transpose() + dcov.transpose() * K * R;
    let mut dR = K.transpose() * dcov * K;
    // A = I - K H.
    dK -= dA * H.transpose();
    let mut dH = -(K.transpose() * dA);
    // x = x- + K y.
    dK += dmean * y.transpose();
    let dy = K.transpose() * dmean;
    // K = U S^-1 with U = P- H^T: dU = dK S^-T, dS = -K^T dK S^-T.
    let S_inv_T = S_inv.transpose();
    let dU = dK * S_inv_T;
    let dS = -(K.transpose() * dK * S_inv_T);
    dPm += dU * H;
    dH += dU.transpose() * cov;
    // S = H P- H^T + R.
    dPm += H.transpose() * dS * H;
    dH += dS * H * cov.transpose() + dS.transpose() * H * cov;
    dR += dS;
    CorrectGrad { mean: *dmean, cov: dPm, z: dy, zhat: -dy, H: dH, R: dR }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dekf::ekf;

    /// Every matrix of a step as one flat vector, so that each element can be
    /// perturbed in turn.
    #[derive(Clone)]
    struct Inputs {
        mean: Vect<6>,
        cov: Mat<6, 6>,
        a: Vect<3>,
        J1: Mat<3, 6>,
        zhat: Vect<3>,
        H: Mat<3, 6>,
        z: Vect<3>,
        R: Mat<3, 3>,
        Q: Mat<6, 6>,
    }

    fn weights<const R: usize, const C: usize>(seed: f64) -> Mat<R, C> {
        Mat::<R, C>::from_fn(|i, j| ((i * 7 + j * 3) as f64 * 0.37 + seed).sin())
    }

    fn spd<const K: usize>(seed: f64, diag: f64) -> Mat<K, K> {
        let L = weights::<K, K>(seed) * 0.3;
        L * L.transpose() + Mat::<K, K>::identity() * diag
    }

    fn inputs() -> Inputs {
        Inputs {
            mean: weights::<6, 1>(0.1),
            cov: spd(0.2, 0.3),
            a: weights::<3, 1>(0.3) * 0.1,
            J1: weights::<3, 6>(0.4) * 0.2,
            zhat: weights::<3, 1>(0.5),
            H: weights::<3, 6>(0.6),
            z: weights::<3, 1>(0.7) * 0.8,
            R: spd(0.8, 0.5),
            Q: spd(0.9, 0.01) * 0.1,
        }
    }

    /// A scalar of the outputs of predict + correct.
    fn loss(i: &Inputs) -> f64 {
        let pr = predict(&i.mean, &i.cov, &i.a, &i.J1, 0.03, &i.Q);
        let co = correct(&pr.mean, &pr.cov, &i.z, &i.zhat, &i.H, &i.R).expect("positive definite");
        weights::<6, 1>(1.1).dot(&co.mean) + weights::<6, 6>(1.2).component_mul(&co.cov).sum()
    }

    #[test]
    fn adjoints_match_finite_differences() {
        let i = inputs();
        let pr = predict(&i.mean, &i.cov, &i.a, &i.J1, 0.03, &i.Q);
        let co = correct(&pr.mean, &pr.cov, &i.z, &i.zhat, &i.H, &i.R).expect("positive definite");
        let cg = correct_backward(&co, &pr.cov, &i.H, &i.R, &weights::<6, 1>(1.1), &weights::<6, 6>(1.2));
        let pg: PredictGrad<6, 3> = predict_backward(&pr, &i.cov, 0.03, &cg.mean, &cg.cov);
        // (name, analytic adjoint, perturbation of element k).
        type Perturb = fn(&mut Inputs, usize, f64);
        let cases: Vec<(&str, Vec<f64>, Perturb)> = vec![
            ("mean", pg.mean.as_slice().to_vec(), |x, k, e| x.mean[k] += e),
            ("cov", pg.cov.as_slice().to_vec(), |x, k, e| x.cov[k] += e),
            ("a", pg.a.as_slice().to_vec(), |x, k, e| x.a[k] += e),
            ("J1", pg.J1.as_slice().to_vec(), |x, k, e| x.J1[k] += e),
            ("Q", pg.Q.as_slice().to_vec(), |x, k, e| x.Q[k] += e),
            ("zhat", cg.zhat.as_slice().to_vec(), |x, k, e| x.zhat[k] += e),
            ("H", cg.H.as_slice().to_vec(), |x, k, e| x.H[k] += e),
            ("z", cg.z.as_slice().to_vec(), |x, k, e| x.z[k] += e),
            ("R", cg.R.as_slice().to_vec(), |x, k, e| x.R[k] += e),
        ];
        let eps = 1e-6;
        for (name, analytic, perturb) in cases {
            for (k, want) in analytic.iter().enumerate() {
                let (mut up, mut down) = (inputs(), inputs());
                perturb(&mut up, k, eps);
                perturb(&mut down, k, -eps);
                let numeric = (loss(&up) - loss(&down)) / (2.0 * eps);
                assert!(
                    (numeric - want).abs() < 1e-6 * (1.0 + want.abs()),
                    "{name}[{k}]: numeric {numeric}, analytic {want}"
                );
            }
        }
    }

    /// With one degree of freedom the vector step is the thesis's scalar
    /// step of [`crate::dekf::ekf`], forward and backward.
    #[test]
    fn one_degree_of_freedom_is_the_scalar_filter() {
        let (mean, cov) = ([0.4, -0.2], [[0.3, 0.05], [0.05, 0.2]]);
        let (a, J1, zhat, H, z, R) = (0.07, [0.1, -0.3], 0.2, [0.8, 1.5], -0.4, 0.5);
        let Q = [[0.01, 0.002], [0.002, 0.03]];
        let m2 = |m: &ekf::M2| Mat::<2, 2>::new(m[0][0], m[0][1], m[1][0], m[1][1]);
        let v2 = |v: [f64; 2]| Vect::<2>::new(v[0], v[1]);
        let h2 = |v: [f64; 2]| Mat::<1, 2>::new(v[0], v[1]);
        let s_pr = ekf::predict(mean, &cov, a, J1, 0.03, &Q);
        let s_co = ekf::correct(s_pr.mean, &s_pr.cov, z, zhat, H, R);
        let v_pr = predict(&v2(mean), &m2(&cov), &Vect::<1>::new(a), &h2(J1), 0.03, &m2(&Q));
        let v_co = correct(
            &v_pr.mean,
            &v_pr.cov,
            &Vect::<1>::new(z),
            &Vect::<1>::new(zhat),
            &h2(H),
            &Mat::<1, 1>::new(R),
        )
        .expect("positive definite");
        let close = |a: &[f64], b: &[f64]| a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-12);
        assert!(close(v_co.mean.as_slice(), &s_co.mean));
        assert!(close(v_co.cov.transpose().as_slice(), &[s_co.cov[0], s_co.cov[1]].concat()));
        let (dmean, dcov) = ([1.3, -0.6], [[0.3, -0.7], [1.1, 0.4]]);
        let s_cg = ekf::correct_backward(&s_co, &s_pr.cov, H, R, dmean, &dcov);
        let s_pg = ekf::predict_backward(&s_pr, &cov, 0.03, s_cg.mean, &s_cg.cov);
        let v_cg = correct_backward(&v_co, &v_pr.cov, &h2(H), &Mat::<1, 1>::new(R), &v2(dmean), &m2(&dcov));
        let v_pg: PredictGrad<2, 1> = predict_backward(&v_pr, &m2(&cov), 0.03, &v_cg.mean, &v_cg.cov);
        assert!(close(v_pg.mean.as_slice(), &s_pg.mean));
        assert!(close(v_pg.cov.transpose().as_slice(), &[s_pg.cov[0], s_pg.cov[1]].concat()));
        assert!(close(&[v_pg.a[0]], &[s_pg.a]));
        assert!(close(v_pg.J1.as_slice(), &s_pg.J1));
        assert!(close(v_cg.H.as_slice(), &s_cg.H));
        assert!(close(&[v_cg.z[0], v_cg.zhat[0], v_cg.R[0]], &[s_cg.z, s_cg.zhat, s_cg.R]));
    }

    #[test]
    fn a_singular_innovation_covariance_only_predicts() {
        let co = correct(
            &Vect::<6>::zeros(),
            &Mat::zeros(),
            &Vect::<3>::zeros(),
            &Vect::zeros(),
            &Mat::zeros(),
            &Mat::zeros(),
        );
        assert!(co.is_none());
    }
}
