//! Loss (2.149) and its gradient for a batch of subsequences, by
//! backpropagation through time (Sec. 2.5.3): the filter runs `T_s` steps from
//! states drawn around the ground truth (2.148), and the gradient flows back
//! through every correction, prediction and network evaluation.
#![expect(non_snake_case, reason = "matrices are named as in the thesis's equations (F, H, Q, R, P, K)")]

use nalgebra::DMatrix;

use super::batch::{BatchGrad, Sequence, Window};
use super::ekf::{
    CorrectGrad, Corrected, M2, MIN_INNOVATION_VAR, Predicted, correct, correct_backward, predict,
    predict_backward,
};
use super::mlp::{Tape, backward, forward};
use super::model::DekfModel;
use super::state::StateKind;

struct Step {
    cov_prev: Vec<M2>,
    J1: Vec<[f64; 2]>,
    pred: Vec<Predicted>,
    H: Vec<[f64; 2]>,
    corr: Vec<Option<Corrected>>,
    mean: Vec<[f64; 2]>,
    t1: Tape,
    t2: Tape,
    t3: Option<Tape>,
}

fn with_tangents(means: &[[f64; 2]]) -> DMatrix<f32> {
    let mut m = DMatrix::<f32>::zeros(2, 3 * means.len());
    for (s, x) in means.iter().enumerate() {
        m[(0, 3 * s)] = x[0] as f32;
        m[(1, 3 * s)] = x[1] as f32;
        m[(0, 3 * s + 1)] = 1.0;
        m[(1, 3 * s + 2)] = 1.0;
    }
    m
}

/// `dmean` (the adjoint of a network's input with its outputs held fixed)
/// plus the path through the network of sample `s`: its input gradient `dx`
/// from the backward pass when there is one (smooth networks: first and
/// second order), else `dvalue J` (ReLU networks, whose Jacobian `J` has a
/// zero derivative).
fn through_network(
    dmean: [f64; 2],
    dvalue: f64,
    J: [f64; 2],
    dx: Option<&DMatrix<f32>>,
    s: usize,
) -> [f64; 2] {
    match dx {
        Some(dx) => [dmean[0] + f64::from(dx[(0, 3 * s)]), dmean[1] + f64::from(dx[(1, 3 * s)])],
        None => [dmean[0] + dvalue * J[0], dmean[1] + dvalue * J[1]],
    }
}

/// Runs the filter over `windows` for `length` steps and backpropagates the
/// sum of squared state errors. Deterministic for given inputs. Any state:
/// a sliding model runs the thesis's scalar filter, a planar one the vector
/// filter of [`super::multi`].
pub fn batch_grad(model: &DekfModel, data: &[Sequence], windows: &[Window], length: usize) -> BatchGrad {
    match model.state() {
        StateKind::Sliding => sliding_batch_grad(model, data, windows, length),
        StateKind::Planar => super::multi::bptt::batch_grad::<6, 3>(model, data, windows, length),
    }
}

/// [`batch_grad`] of a sliding model: the thesis's filter of [`super::ekf`].
#[expect(
    clippy::too_many_lines,
    reason = "one function on purpose: the reverse pass mirrors the forward pass step by step over the same tape, and keeping both in view makes a mismatch visible (the finite-difference tests check them)"
)]
fn sliding_batch_grad(model: &DekfModel, data: &[Sequence], windows: &[Window], length: usize) -> BatchGrad {
    let p = &model.params;
    let l = &model.layout;
    let n = windows.len();
    let c = l.channels;
    let dt = model.meta.dt_s;
    let Q = model.process_noise();
    let R = model.measurement_noise();
    let p0 = [model.meta.p0_diag[0], model.meta.p0_diag[1]];
    let mut mean: Vec<[f64; 2]> = windows.iter().map(|w| [w.mean0[0], w.mean0[1]]).collect();
    let mut cov: Vec<M2> = vec![[[p0[0], 0.0], [0.0, p0[1]]]; n];
    let mut steps: Vec<Step> = Vec::with_capacity(length);
    let mut out =
        BatchGrad { squared_error: 0.0, squared_error_pv: [0.0; 2], states: 0, grad: vec![0.0; l.len] };

    for k in 1..=length {
        let (y1, t1) = forward(p, &l.motion, with_tangents(&mean), 3, true);
        let J1: Vec<[f64; 2]> =
            (0..n).map(|s| [f64::from(y1[(0, 3 * s + 1)]), f64::from(y1[(0, 3 * s + 2)])]).collect();
        let pred: Vec<Predicted> =
            (0..n).map(|s| predict(mean[s], &cov[s], f64::from(y1[(0, 3 * s)]), J1[s], dt, &Q)).collect();
        let pm: Vec<[f64; 2]> = pred.iter().map(|x| x.mean).collect();
        let (y2, t2) = forward(p, &l.measurement, with_tangents(&pm), 3, true);
        let H: Vec<[f64; 2]> =
            (0..n).map(|s| [f64::from(y2[(0, 3 * s + 1)]), f64::from(y2[(0, 3 * s + 2)])]).collect();
        let mut x3 = DMatrix::<f32>::zeros(c, n);
        for (s, w) in windows.iter().enumerate() {
            let t = w.start + k;
            x3.column_mut(s).copy_from_slice(&data[w.sequence].measurements[t * c..(t + 1) * c]);
        }
        let (y3, t3) = forward(p, &l.feature, x3, 1, true);
        let mut corr = Vec::with_capacity(n);
        mean.clear();
        let cov_prev = std::mem::take(&mut cov);
        for (s, w) in windows.iter().enumerate() {
            let t = w.start + k;
            let pr = &pred[s];
            let h = H[s];
            let S = h[0] * (pr.cov[0][0] * h[0] + pr.cov[0][1] * h[1])
                + h[1] * (pr.cov[1][0] * h[0] + pr.cov[1][1] * h[1])
                + R;
            let co = (data[w.sequence].valid[t] && S > MIN_INNOVATION_VAR)
                .then(|| correct(pr.mean, &pr.cov, f64::from(y3[(0, s)]), f64::from(y2[(0, 3 * s)]), h, R))
                .filter(|co| co.mean.iter().chain(co.cov.iter().flatten()).all(|v| v.is_finite()));
            let (m, cv) = co.as_ref().map_or((pr.mean, pr.cov), |co| (co.mean, co.cov));
            let truth = data[w.sequence].truth_at(t);
            let e = [m[0] - truth[0] - w.position_shift[0], m[1] - truth[1]];
            out.squared_error_pv[0] += e[0] * e[0];
            out.squared_error_pv[1] += e[1] * e[1];
            mean.push(m);
            cov.push(cv);
            corr.push(co);
        }
        out.states += n;
        let (Some(t1), Some(t2)) = (t1, t2) else { unreachable!("forward keeps its tape when asked") };
        steps.push(Step { cov_prev, J1, pred, H, corr, mean: mean.clone(), t1, t2, t3 });
    }
    out.squared_error = out.squared_error_pv[0] + out.squared_error_pv[1];

    // Reverse pass.
    let mut dmean = vec![[0.0f64; 2]; n];
    let mut dcov = vec![[[0.0f64; 2]; 2]; n];
    let mut dQ = [[0.0f64; 2]; 2];
    let mut dR = 0.0f64;
    // Smooth networks: the mean's adjoint through a network comes from its
    // backward pass (with the Hessian terms of the Jacobians); ReLU networks
    // have none, and it is `d(output) J` (see `ekf`'s module doc).
    let curved = l.architecture.activation.has_curvature();
    let mut cgs: Vec<CorrectGrad> = Vec::with_capacity(n);
    let mut da = vec![0.0f64; n];
    for (k, step) in steps.iter().enumerate().rev() {
        let t_of = |w: &Window| w.start + k + 1;
        let mut dy2 = DMatrix::<f32>::zeros(1, 3 * n);
        let mut dy3 = DMatrix::<f32>::zeros(1, n);
        let mut dy1 = DMatrix::<f32>::zeros(1, 3 * n);
        cgs.clear();
        for (s, w) in windows.iter().enumerate() {
            let truth = data[w.sequence].truth_at(t_of(w));
            let m = step.mean[s];
            // d/dmu of |x_gt - mu|^2.
            dmean[s][0] += 2.0 * (m[0] - truth[0] - w.position_shift[0]);
            dmean[s][1] += 2.0 * (m[1] - truth[1]);
            let pr = &step.pred[s];
            cgs.push(match &step.corr[s] {
                Some(co) => {
                    let g = correct_backward(co, &pr.cov, step.H[s], R, dmean[s], &dcov[s]);
                    dR += g.R;
                    dy2[(0, 3 * s)] = g.zhat as f32;
                    dy2[(0, 3 * s + 1)] = g.H[0] as f32;
                    dy2[(0, 3 * s + 2)] = g.H[1] as f32;
                    dy3[(0, s)] = g.z as f32;
                    g
                }
                None => CorrectGrad { mean: dmean[s], cov: dcov[s], ..CorrectGrad::default() },
            });
        }
        let dx2 = backward(p, &mut out.grad, &l.measurement, &step.t2, &dy2, curved);
        if let Some(t3) = &step.t3 {
            backward(p, &mut out.grad, &l.feature, t3, &dy3, false);
        }
        for (s, cg) in cgs.iter().enumerate() {
            let dpred = through_network(cg.mean, cg.zhat, step.H[s], dx2.as_ref(), s);
            let pg = predict_backward(&step.pred[s], &step.cov_prev[s], model.meta.dt_s, dpred, &cg.cov);
            for (row, grad_row) in dQ.iter_mut().zip(&pg.Q) {
                for (d, g) in row.iter_mut().zip(grad_row) {
                    *d += g;
                }
            }
            da[s] = pg.a;
            dy1[(0, 3 * s)] = pg.a as f32;
            dy1[(0, 3 * s + 1)] = pg.J1[0] as f32;
            dy1[(0, 3 * s + 2)] = pg.J1[1] as f32;
            dmean[s] = pg.mean;
            dcov[s] = pg.cov;
        }
        let dx1 = backward(p, &mut out.grad, &l.motion, &step.t1, &dy1, curved);
        for (s, dm) in dmean.iter_mut().enumerate() {
            *dm = through_network(*dm, da[s], step.J1[s], dx1.as_ref(), s);
        }
    }
    // Q = L L^T: dL = (dQ + dQ^T) L, lower triangle; R = L_R^2: dL_R = 2 L_R dR.
    let o = l.process_noise;
    let L = [[f64::from(p[o]), 0.0], [f64::from(p[o + 2]), f64::from(p[o + 3])]];
    let sym = [[2.0 * dQ[0][0], dQ[0][1] + dQ[1][0]], [dQ[1][0] + dQ[0][1], 2.0 * dQ[1][1]]];
    out.grad[o] += (sym[0][0] * L[0][0] + sym[0][1] * L[1][0]) as f32;
    out.grad[o + 2] += (sym[1][0] * L[0][0] + sym[1][1] * L[1][0]) as f32;
    out.grad[o + 3] += (sym[1][1] * L[1][1]) as f32;
    let lr = f64::from(p[l.measurement_noise]);
    out.grad[l.measurement_noise] += (2.0 * lr * dR) as f32;
    out
}
