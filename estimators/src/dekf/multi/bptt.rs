//! The loss (2.149) and its gradient for a model of `M` degrees of freedom
//! by backpropagation through time: [`crate::dekf::batch_grad`]'s algorithm
//! with the vector filter of [`super::ekf`]. NN1 and NN2 carry `N` tangent
//! columns (one per state component), so their outputs give the `M x N`
//! Jacobians `F`'s lower block and `H` needs.
#![expect(non_snake_case, reason = "matrices are named as in the thesis's equations (F, H, Q, R, P, K)")]

use nalgebra::DMatrix;

use super::ekf::{
    CorrectGrad, Corrected, Mat, Predicted, Vect, correct, correct_backward, predict, predict_backward,
};
use crate::dekf::batch::{BatchGrad, Sequence, Window};
use crate::dekf::mlp::{Tape, backward, forward};
use crate::dekf::model::DekfModel;

/// `Q` and `R` of `model` and their Cholesky factors, as fixed-size matrices.
pub(crate) struct Noise<const N: usize, const M: usize> {
    pub Q: Mat<N, N>,
    pub R: Mat<M, M>,
    pub L_Q: Mat<N, N>,
    pub L_R: Mat<M, M>,
}

impl<const N: usize, const M: usize> Noise<N, M> {
    pub fn of(model: &DekfModel) -> Noise<N, M> {
        let (lq, lr) = (model.process_noise_factor(), model.measurement_noise_factor());
        let L_Q = Mat::<N, N>::from_fn(|r, c| lq[(r, c)]);
        let L_R = Mat::<M, M>::from_fn(|r, c| lr[(r, c)]);
        Noise { Q: L_Q * L_Q.transpose(), R: L_R * L_R.transpose(), L_Q, L_R }
    }
}

/// The network input of samples at `means`: per sample a value column and
/// `N` unit tangent columns.
pub(crate) fn with_tangents<const N: usize>(means: &[Vect<N>]) -> DMatrix<f32> {
    let c = N + 1;
    let mut m = DMatrix::<f32>::zeros(N, c * means.len());
    for (s, x) in means.iter().enumerate() {
        for i in 0..N {
            m[(i, c * s)] = x[i] as f32;
            m[(i, c * s + 1 + i)] = 1.0;
        }
    }
    m
}

/// The value and Jacobian of sample `s` in a network's output with tangents.
pub(crate) fn value_and_jacobian<const N: usize, const M: usize>(
    y: &DMatrix<f32>,
    s: usize,
) -> (Vect<M>, Mat<M, N>) {
    let c = N + 1;
    let value = Vect::<M>::from_fn(|i, _| f64::from(y[(i, c * s)]));
    let J = Mat::<M, N>::from_fn(|i, j| f64::from(y[(i, c * s + 1 + j)]));
    (value, J)
}

struct Step<const N: usize, const M: usize> {
    cov_prev: Vec<Mat<N, N>>,
    J1: Vec<Mat<M, N>>,
    pred: Vec<Predicted<N>>,
    H: Vec<Mat<M, N>>,
    corr: Vec<Option<Corrected<N, M>>>,
    mean: Vec<Vect<N>>,
    t1: Tape,
    t2: Tape,
    t3: Option<Tape>,
}

/// The mean's adjoint plus the path through the network of sample `s`: the
/// input gradient of its backward pass (smooth networks), else `J^T dvalue`.
fn through_network<const N: usize, const M: usize>(
    dmean: &Vect<N>,
    dvalue: &Vect<M>,
    J: &Mat<M, N>,
    dx: Option<&DMatrix<f32>>,
    s: usize,
) -> Vect<N> {
    match dx {
        Some(dx) => Vect::<N>::from_fn(|i, _| dmean[i] + f64::from(dx[(i, (N + 1) * s)])),
        None => dmean + J.transpose() * dvalue,
    }
}

/// `dL = (dX + dX^T) L`, lower triangle, added to the row-major factor at `offset`.
fn cholesky_grad<const K: usize>(grad: &mut [f32], offset: usize, dX: &Mat<K, K>, L: &Mat<K, K>) {
    let dL = (dX + dX.transpose()) * L;
    for r in 0..K {
        for c in 0..=r {
            grad[offset + r * K + c] += dL[(r, c)] as f32;
        }
    }
}

/// Runs the filter over `windows` for `length` steps and backpropagates the
/// sum of squared state errors (the model's state has `N = 2 M` components).
#[expect(
    clippy::too_many_lines,
    reason = "the reverse pass mirrors the forward pass step by step, as in the one-dimensional batch_grad"
)]
pub fn batch_grad<const N: usize, const M: usize>(
    model: &DekfModel,
    data: &[Sequence],
    windows: &[Window],
    length: usize,
) -> BatchGrad {
    let p = &model.params;
    let l = &model.layout;
    let (n, c, cols) = (windows.len(), l.channels, N + 1);
    let dt = model.meta.dt_s;
    let noise = Noise::<N, M>::of(model);
    let P0 = Mat::<N, N>::from_fn(|r, k| if r == k { model.meta.p0_diag[r] } else { 0.0 });
    let mut mean: Vec<Vect<N>> = windows.iter().map(|w| Vect::<N>::from_fn(|i, _| w.mean0[i])).collect();
    let mut cov: Vec<Mat<N, N>> = vec![P0; n];
    let mut steps: Vec<Step<N, M>> = Vec::with_capacity(length);
    let mut out =
        BatchGrad { squared_error: 0.0, squared_error_pv: [0.0; 2], states: 0, grad: vec![0.0; l.len] };
    let target = |w: &Window, t: usize| {
        let truth = data[w.sequence].truth_at(t);
        Vect::<N>::from_fn(|i, _| if i < M { truth[i] + w.position_shift[i] } else { truth[i] })
    };

    for k in 1..=length {
        let (y1, t1) = forward(p, &l.motion, with_tangents(&mean), cols, true);
        let mut J1 = Vec::with_capacity(n);
        let mut pred = Vec::with_capacity(n);
        for s in 0..n {
            let (a, J) = value_and_jacobian::<N, M>(&y1, s);
            pred.push(predict(&mean[s], &cov[s], &a, &J, dt, &noise.Q));
            J1.push(J);
        }
        let pm: Vec<Vect<N>> = pred.iter().map(|x| x.mean).collect();
        let (y2, t2) = forward(p, &l.measurement, with_tangents(&pm), cols, true);
        let mut x3 = DMatrix::<f32>::zeros(c, n);
        for (s, w) in windows.iter().enumerate() {
            let t = w.start + k;
            x3.column_mut(s).copy_from_slice(&data[w.sequence].measurements[t * c..(t + 1) * c]);
        }
        let (y3, t3) = forward(p, &l.feature, x3, 1, true);
        let mut corr = Vec::with_capacity(n);
        let mut H = Vec::with_capacity(n);
        mean.clear();
        let cov_prev = std::mem::take(&mut cov);
        for (s, w) in windows.iter().enumerate() {
            let t = w.start + k;
            let pr = &pred[s];
            let (zhat, h) = value_and_jacobian::<N, M>(&y2, s);
            let z = Vect::<M>::from_fn(|i, _| f64::from(y3[(i, s)]));
            let co = data[w.sequence].valid[t]
                .then(|| correct(&pr.mean, &pr.cov, &z, &zhat, &h, &noise.R))
                .flatten()
                .filter(|co| co.mean.iter().chain(co.cov.iter()).all(|v| v.is_finite()));
            let (m, cv) = co.as_ref().map_or((pr.mean, pr.cov), |co| (co.mean, co.cov));
            // A step without a truth (NaN: the marker was not seen) adds no loss.
            let e = m - target(w, t);
            if e.iter().all(|v| v.is_finite()) {
                out.squared_error_pv[0] += e.rows(0, M).norm_squared();
                out.squared_error_pv[1] += e.rows(M, M).norm_squared();
                out.states += 1;
            }
            mean.push(m);
            cov.push(cv);
            corr.push(co);
            H.push(h);
        }
        let (Some(t1), Some(t2)) = (t1, t2) else { unreachable!("forward keeps its tape when asked") };
        steps.push(Step { cov_prev, J1, pred, H, corr, mean: mean.clone(), t1, t2, t3 });
    }
    out.squared_error = out.squared_error_pv[0] + out.squared_error_pv[1];

    // Reverse pass.
    let mut dmean = vec![Vect::<N>::zeros(); n];
    let mut dcov = vec![Mat::<N, N>::zeros(); n];
    let mut dQ = Mat::<N, N>::zeros();
    let mut dR = Mat::<M, M>::zeros();
    let curved = l.architecture.activation.has_curvature();
    let mut cgs: Vec<CorrectGrad<N, M>> = Vec::with_capacity(n);
    let mut da = vec![Vect::<M>::zeros(); n];
    for (k, step) in steps.iter().enumerate().rev() {
        let mut dy2 = DMatrix::<f32>::zeros(M, cols * n);
        let mut dy3 = DMatrix::<f32>::zeros(M, n);
        let mut dy1 = DMatrix::<f32>::zeros(M, cols * n);
        cgs.clear();
        for (s, w) in windows.iter().enumerate() {
            // d/dmu of |x_gt - mu|^2, where there is a truth.
            let e = step.mean[s] - target(w, w.start + k + 1);
            if e.iter().all(|v| v.is_finite()) {
                dmean[s] += 2.0 * e;
            }
            let pr = &step.pred[s];
            cgs.push(match &step.corr[s] {
                Some(co) => {
                    let g = correct_backward(co, &pr.cov, &step.H[s], &noise.R, &dmean[s], &dcov[s]);
                    dR += g.R;
                    for i in 0..M {
                        dy2[(i, cols * s)] = g.zhat[i] as f32;
                        for j in 0..N {
                            dy2[(i, cols * s + 1 + j)] = g.H[(i, j)] as f32;
                        }
                        dy3[(i, s)] = g.z[i] as f32;
                    }
                    g
                }
                None => CorrectGrad::passing(dmean[s], dcov[s]),
            });
        }
        let dx2 = backward(p, &mut out.grad, &l.measurement, &step.t2, &dy2, curved);
        if let Some(t3) = &step.t3 {
            backward(p, &mut out.grad, &l.feature, t3, &dy3, false);
        }
        for (s, cg) in cgs.iter().enumerate() {
            let dpred = through_network(&cg.mean, &cg.zhat, &step.H[s], dx2.as_ref(), s);
            let pg = predict_backward::<N, M>(&step.pred[s], &step.cov_prev[s], dt, &dpred, &cg.cov);
            dQ += pg.Q;
            da[s] = pg.a;
            for i in 0..M {
                dy1[(i, cols * s)] = pg.a[i] as f32;
                for j in 0..N {
                    dy1[(i, cols * s + 1 + j)] = pg.J1[(i, j)] as f32;
                }
            }
            dmean[s] = pg.mean;
            dcov[s] = pg.cov;
        }
        let dx1 = backward(p, &mut out.grad, &l.motion, &step.t1, &dy1, curved);
        for (s, dm) in dmean.iter_mut().enumerate() {
            *dm = through_network(dm, &da[s], &step.J1[s], dx1.as_ref(), s);
        }
    }
    // Q = L_Q L_Q^T, R = L_R L_R^T.
    cholesky_grad(&mut out.grad, l.process_noise, &dQ, &noise.L_Q);
    cholesky_grad(&mut out.grad, l.measurement_noise, &dR, &noise.L_R);
    out
}
