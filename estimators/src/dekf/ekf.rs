//! One step of the dEKF's Extended Kalman filter (Algorithm 3 with the models
//! of Sec. 6.1.3-6.1.4), and its reverse-mode derivative for training.
//!
//! State `x = (p, v)` in cm and cm/s. Prediction (6.3):
//! `x- = (p + v dt, v + a)`, `a = NN1(x)`, `F = df/dx = [[1, dt], [J1_p, 1 + J1_v]]`,
//! `P- = F P F^T + Q`, `Q = L_Q L_Q^T`. Correction (6.5)-(6.6) with the scalar
//! feature `z = NN3(tau')` and `z^ = NN2(x-)`, `H = dNN2/dx` at `x-`:
//! `S = H P- H^T + R`, `R = L_R^2`, `K = P- H^T / S`, `x = x- + K (z - z^)`,
//! `P = (I - K H) P- (I - K H)^T + K R K^T` (Joseph form).
//!
//! The reverse-mode functions treat the networks' outputs (`a`, `J1`, `z`,
//! `zhat`, `H`) as inputs and return their adjoints; the mean adjoints they
//! return exclude the paths through the networks, which depend on the mean
//! too. The caller adds those: `d(a)/dx = J1` and `d(J1)/dx = d2 NN1/dx2`
//! (and likewise for NN2 with `zhat` and `H`). The second-order part is zero
//! for ReLU networks (piecewise linear, so their Jacobians are piecewise
//! constant) but not for smooth activations; [`super::mlp::backward`]
//! computes both parts from the tape.
#![expect(non_snake_case, reason = "matrices are named as in the thesis's equations (F, H, Q, R, P, K)")]

/// A 2x2 matrix, row-major.
pub type M2 = [[f64; 2]; 2];

/// Smallest innovation variance `S` for which the filter corrects; below it
/// the measurement carries no usable information and the step only predicts.
pub const MIN_INNOVATION_VAR: f64 = 1e-12;

fn mul(a: &M2, b: &M2) -> M2 {
    let mut c = [[0.0; 2]; 2];
    for i in 0..2 {
        for j in 0..2 {
            c[i][j] = a[i][0] * b[0][j] + a[i][1] * b[1][j];
        }
    }
    c
}

fn tr(a: &M2) -> M2 {
    [[a[0][0], a[1][0]], [a[0][1], a[1][1]]]
}

fn add(a: &M2, b: &M2) -> M2 {
    [[a[0][0] + b[0][0], a[0][1] + b[0][1]], [a[1][0] + b[1][0], a[1][1] + b[1][1]]]
}

/// `L L^T` for the lower-triangular `[l00, l10, l11]`.
pub fn q_from_cholesky(l00: f64, l10: f64, l11: f64) -> M2 {
    [[l00 * l00, l00 * l10], [l00 * l10, l10 * l10 + l11 * l11]]
}

/// The quantities of one prediction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Predicted {
    /// `x-`.
    pub mean: [f64; 2],
    /// `P-`.
    pub cov: M2,
    /// `F`.
    pub F: M2,
}

/// Prediction from `(mean, cov)` with NN1's output `a` and Jacobian `J1`.
pub fn predict(mean: [f64; 2], cov: &M2, a: f64, J1: [f64; 2], dt: f64, Q: &M2) -> Predicted {
    let F = [[1.0, dt], [J1[0], 1.0 + J1[1]]];
    let m = [mean[0] + mean[1] * dt, mean[1] + a];
    let c = add(&mul(&mul(&F, cov), &tr(&F)), Q);
    Predicted { mean: m, cov: c, F }
}

/// Adjoints flowing out of a prediction.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PredictGrad {
    /// d loss / d previous mean with NN1's outputs `a` and `J1` held fixed
    /// (the caller adds the paths through NN1, see the module's doc).
    pub mean: [f64; 2],
    /// d loss / d previous covariance.
    pub cov: M2,
    /// d loss / d a (NN1's output).
    pub a: f64,
    /// d loss / d J1 (NN1's Jacobian).
    pub J1: [f64; 2],
    /// d loss / d Q.
    pub Q: M2,
}

/// Reverse of [`predict`]: from the adjoints of `x-` and `P-`. NN1's
/// outputs are held fixed: the returned mean adjoint lacks
/// `da J1 + (d2 NN1/dx2) dJ1`, which the caller adds.
pub fn predict_backward(pred: &Predicted, cov: &M2, dt: f64, dmean: [f64; 2], dcov: &M2) -> PredictGrad {
    let F = &pred.F;
    // P- = F P F^T + Q: dP = F^T dP- F, dF = dP- F P^T + dP-^T F P.
    let dP = mul(&mul(&tr(F), dcov), F);
    let dF = add(&mul(&mul(dcov, F), &tr(cov)), &mul(&mul(&tr(dcov), F), cov));
    let da = dmean[1];
    // x- = (p + v dt, v + a), `a` held fixed.
    let dmean_prev = [dmean[0], dmean[0] * dt + dmean[1]];
    PredictGrad { mean: dmean_prev, cov: dP, a: da, J1: [dF[1][0], dF[1][1]], Q: *dcov }
}

/// The quantities of one correction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Corrected {
    /// `x`.
    pub mean: [f64; 2],
    /// `P`.
    pub cov: M2,
    /// `S`.
    pub S: f64,
    /// `K`.
    pub K: [f64; 2],
    /// `z - z^`.
    pub innovation: f64,
}

/// Correction of the prediction `(mean, cov)` with the feature `z`, NN2's
/// output `zhat` and Jacobian `H` at the predicted mean, and `R`.
pub fn correct(mean: [f64; 2], cov: &M2, z: f64, zhat: f64, H: [f64; 2], R: f64) -> Corrected {
    let u = [cov[0][0] * H[0] + cov[0][1] * H[1], cov[1][0] * H[0] + cov[1][1] * H[1]];
    let S = H[0] * u[0] + H[1] * u[1] + R;
    let K = [u[0] / S, u[1] / S];
    let y = z - zhat;
    let m = [mean[0] + K[0] * y, mean[1] + K[1] * y];
    let A = [[1.0 - K[0] * H[0], -K[0] * H[1]], [-K[1] * H[0], 1.0 - K[1] * H[1]]];
    let KRK = [[R * K[0] * K[0], R * K[0] * K[1]], [R * K[1] * K[0], R * K[1] * K[1]]];
    let c = add(&mul(&mul(&A, cov), &tr(&A)), &KRK);
    Corrected { mean: m, cov: c, S, K, innovation: y }
}

/// Adjoints flowing out of a correction.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CorrectGrad {
    /// d loss / d predicted mean with NN2's outputs `zhat` and `H` held
    /// fixed (the caller adds the paths through NN2, see the module's doc).
    pub mean: [f64; 2],
    /// d loss / d predicted covariance.
    pub cov: M2,
    /// d loss / d z (NN3's output).
    pub z: f64,
    /// d loss / d zhat (NN2's output).
    pub zhat: f64,
    /// d loss / d H (NN2's Jacobian).
    pub H: [f64; 2],
    /// d loss / d R.
    pub R: f64,
}

/// Reverse of [`correct`]. NN2's outputs are held fixed: the returned mean
/// adjoint lacks `dzhat H + (d2 NN2/dx2) dH`, which the caller adds.
pub fn correct_backward(
    c: &Corrected,
    cov: &M2,
    H: [f64; 2],
    R: f64,
    dmean: [f64; 2],
    dcov: &M2,
) -> CorrectGrad {
    let K = c.K;
    let S = c.S;
    let y = c.innovation;
    let A = [[1.0 - K[0] * H[0], -K[0] * H[1]], [-K[1] * H[0], 1.0 - K[1] * H[1]]];
    // P = A P- A^T + R K K^T.
    let sym = add(dcov, &tr(dcov));
    let dA = mul(&mul(&sym, &A), cov);
    let mut dPm = mul(&mul(&tr(&A), dcov), &A);
    let mut dK = [R * (sym[0][0] * K[0] + sym[0][1] * K[1]), R * (sym[1][0] * K[0] + sym[1][1] * K[1])];
    let mut dR =
        dcov[0][0] * K[0] * K[0] + (dcov[0][1] + dcov[1][0]) * K[0] * K[1] + dcov[1][1] * K[1] * K[1];
    // A = I - K H.
    let mut dH = [0.0; 2];
    for i in 0..2 {
        for j in 0..2 {
            dK[i] -= dA[i][j] * H[j];
            dH[j] -= K[i] * dA[i][j];
        }
    }
    // x = x- + K y.
    let dmean_pred = dmean;
    dK[0] += dmean[0] * y;
    dK[1] += dmean[1] * y;
    let dy = dmean[0] * K[0] + dmean[1] * K[1];
    // K = u / S with u = P- H^T: dK/dS = -u / S^2 = -K / S.
    let du = [dK[0] / S, dK[1] / S];
    let dS = -(dK[0] * K[0] + dK[1] * K[1]) / S;
    for i in 0..2 {
        for j in 0..2 {
            dPm[i][j] += du[i] * H[j];
            dH[j] += du[i] * cov[i][j];
        }
    }
    // S = H P- H^T + R.
    for i in 0..2 {
        for j in 0..2 {
            dPm[i][j] += dS * H[i] * H[j];
            dH[i] += dS * cov[i][j] * H[j];
            dH[j] += dS * H[i] * cov[i][j];
        }
    }
    dR += dS;
    // y = z - zhat.
    let dzhat = -dy;
    CorrectGrad { mean: dmean_pred, cov: dPm, z: dy, zhat: dzhat, H: dH, R: dR }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A scalar function of the outputs of predict + correct, for finite differences.
    #[expect(
        clippy::too_many_arguments,
        reason = "every input of predict + correct, perturbed one at a time"
    )]
    fn loss(
        mean: [f64; 2],
        cov: &M2,
        a: f64,
        J1: [f64; 2],
        zhat: f64,
        H: [f64; 2],
        z: f64,
        R: f64,
        Q: &M2,
    ) -> f64 {
        let pr = predict(mean, cov, a, J1, 0.03, Q);
        let co = correct(pr.mean, &pr.cov, z, zhat, H, R);
        let w = [[0.3, -0.7], [1.1, 0.4]];
        1.3 * co.mean[0] - 0.6 * co.mean[1]
            + (0..2).map(|i| (0..2).map(|j| w[i][j] * co.cov[i][j]).sum::<f64>()).sum::<f64>()
    }

    #[test]
    fn adjoints_match_finite_differences() {
        let mean = [0.4, -0.2];
        let cov = [[0.3, 0.05], [0.05, 0.2]];
        let (a, J1, zhat, H, z, R) = (0.07, [0.1, -0.3], 0.2, [0.8, 1.5], -0.4, 0.5);
        let Q = [[0.01, 0.002], [0.002, 0.03]];
        let pr = predict(mean, &cov, a, J1, 0.03, &Q);
        let co = correct(pr.mean, &pr.cov, z, zhat, H, R);
        let dmean = [1.3, -0.6];
        let dcov = [[0.3, -0.7], [1.1, 0.4]];
        // zhat, H, a and J1 are inputs here (held fixed), as the adjoints
        // assume.
        let cg = correct_backward(&co, &pr.cov, H, R, dmean, &dcov);
        let pg = predict_backward(&pr, &cov, 0.03, cg.mean, &cg.cov);
        let f = |d: &dyn Fn(&mut [f64; 16])| {
            let mut v = [
                mean[0], mean[1], cov[0][0], cov[0][1], cov[1][0], cov[1][1], a, J1[0], J1[1], zhat, H[0],
                H[1], z, R, Q[0][0], Q[1][1],
            ];
            d(&mut v);
            let q = [[v[14], Q[0][1]], [Q[1][0], v[15]]];
            loss(
                [v[0], v[1]],
                &[[v[2], v[3]], [v[4], v[5]]],
                v[6],
                [v[7], v[8]],
                v[9],
                [v[10], v[11]],
                v[12],
                v[13],
                &q,
            )
        };
        let analytic = [
            pg.mean[0],
            pg.mean[1],
            pg.cov[0][0],
            pg.cov[0][1],
            pg.cov[1][0],
            pg.cov[1][1],
            pg.a,
            pg.J1[0],
            pg.J1[1],
            cg.zhat,
            cg.H[0],
            cg.H[1],
            cg.z,
            cg.R,
            pg.Q[0][0],
            pg.Q[1][1],
        ];
        let eps = 1e-6;
        for (k, want) in analytic.iter().enumerate() {
            let up = f(&|v| v[k] += eps);
            let down = f(&|v| v[k] -= eps);
            let numeric = (up - down) / (2.0 * eps);
            assert!(
                (numeric - want).abs() < 1e-6 * (1.0 + want.abs()),
                "input {k}: numeric {numeric}, analytic {want}"
            );
        }
    }

    #[test]
    fn a_zero_jacobian_ignores_the_measurement() {
        let co = correct([1.0, 2.0], &[[0.1, 0.0], [0.0, 0.1]], 5.0, 0.0, [0.0, 0.0], 1.0);
        assert_eq!(co.mean, [1.0, 2.0]);
        assert_eq!(co.K, [0.0, 0.0]);
    }
}
