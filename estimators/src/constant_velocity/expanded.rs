//! The constant-velocity model's Kalman filter written out for two states
//! and one measurement, without matrices: `F(dt)`, `Q(dt)` (through
//! [`CvParams::q_diag`]), `H = [1, 0]` and `R` of [`CvParams`] expanded by
//! hand. The tuner's likelihood runs it thousands of times per tuning; the
//! module's tests check it against the matrix form.

use super::params::CvParams;

/// A belief of the model as plain numbers.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct ExpandedBelief {
    /// Mean `(p (m), v (m/s))`.
    pub(super) x: [f64; 2],
    /// Covariance (m^2, m^2/s; m^2/s, m^2/s^2), kept symmetric.
    pub(super) p: [[f64; 2]; 2],
}

impl ExpandedBelief {
    /// [`CvParams::initial`].
    pub(super) fn initial(params: &CvParams) -> ExpandedBelief {
        let [pp, vv] = params.p0_diag;
        ExpandedBelief { x: params.x0, p: [[pp, 0.0], [0.0, vv]] }
    }

    /// The prediction over `dt_s`: `x = F x`, `P = F P F^T + Q(dt)` with
    /// `F = [[1, dt], [0, 1]]`.
    pub(super) fn predict(&mut self, params: &CvParams, dt_s: f64) {
        let (x, p) = (self.x, self.p);
        let [q_pp, q_vv] = params.q_diag(dt_s);
        self.x = [x[0] + dt_s * x[1], x[1]];
        let p00 = p[0][0] + 2.0 * dt_s * p[0][1] + dt_s * dt_s * p[1][1] + q_pp;
        let p01 = p[0][1] + dt_s * p[1][1];
        let p11 = p[1][1] + q_vv;
        self.p = [[p00, p01], [p01, p11]];
    }

    /// The innovation of the position `z_m` (m): `(z - H x (m), S = H P H^T + R (m^2))`.
    pub(super) fn innovation(&self, params: &CvParams, z_m: f64) -> (f64, f64) {
        (z_m - self.x[0], self.p[0][0] + params.r_m2)
    }

    /// The correction with the innovation `nu` (m) of variance `s_m2`:
    /// `K = P H^T / S`, `x += K nu`, `P = (I - K H) P` (the simple form, not
    /// Joseph's: the likelihood needs only `S`).
    pub(super) fn correct(&mut self, nu: f64, s_m2: f64) {
        let (x, p) = (self.x, self.p);
        let k = [p[0][0] / s_m2, p[0][1] / s_m2];
        self.x = [x[0] + k[0] * nu, x[1] + k[1] * nu];
        let p01 = p[0][1] - k[0] * p[0][1];
        self.p = [[p[0][0] - k[0] * p[0][0], p01], [p01, p[1][1] - k[1] * p[0][1]]];
    }
}
