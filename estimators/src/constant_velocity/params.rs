//! [`CvParams`]: the constant-velocity model's parameters and matrices.

use nalgebra::{SMatrix, SVector};

use crate::kf::Gaussian;
use crate::rts::{Gate, Measurement, Transition};

/// The constant-velocity model's parameters, in SI units: process noise
/// densities, measurement noise, initial belief and innovation gate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CvParams {
    /// Spectral density of the position random walk, `q_p` (m^2/s).
    pub q_position_m2_per_s: f64,
    /// Spectral density of the velocity random walk, `q_v` ((m/s)^2/s = m^2/s^3).
    pub q_velocity_m2_per_s3: f64,
    /// Variance of one position measurement, `R` (m^2).
    pub r_m2: f64,
    /// Initial state `(p0 (m), v0 (m/s))`, the belief at the first sample
    /// before its measurement.
    pub x0: [f64; 2],
    /// Initial covariance `diag(P0_pp (m^2), P0_vv ((m/s)^2))`.
    pub p0_diag: [f64; 2],
    /// Innovation gate on the marker positions; `None` accepts every one.
    pub gate: Option<Gate>,
}

impl CvParams {
    /// Parameters from a per-step `Q = diag(q[0], q[1])` and `R` given for
    /// steps of `dt_s` seconds (the thesis: `[0.01, 0.01]`, 10, 1/30 s) and
    /// expressed in a length unit of `unit_m` metres (0.01 for cm). The
    /// returned densities give the same `Q` at `dt_s` steps, in metres.
    pub fn from_per_step(q: [f64; 2], r: f64, dt_s: f64, unit_m: f64) -> CvParams {
        let u2 = unit_m * unit_m;
        CvParams {
            q_position_m2_per_s: q[0] * u2 / dt_s,
            q_velocity_m2_per_s3: q[1] * u2 / dt_s,
            r_m2: r * u2,
            ..CvParams::default()
        }
    }

    /// `F(dt)` (eq. 6.13).
    #[rustfmt::skip]
    pub fn F(dt_s: f64) -> SMatrix<f64, 2, 2> {
        SMatrix::<f64, 2, 2>::new(
            1.0, dt_s,
            0.0, 1.0,
        )
    }

    /// The diagonal of `Q(dt)`: `(q_p dt (m^2), q_v dt ((m/s)^2))`.
    pub fn q_diag(&self, dt_s: f64) -> [f64; 2] {
        [self.q_position_m2_per_s * dt_s, self.q_velocity_m2_per_s3 * dt_s]
    }

    /// `Q(dt) = diag(q_p, q_v) dt`.
    pub fn Q(&self, dt_s: f64) -> SMatrix<f64, 2, 2> {
        let [q_pp, q_vv] = self.q_diag(dt_s);
        SMatrix::<f64, 2, 2>::new(q_pp, 0.0, 0.0, q_vv)
    }

    /// `H = [1, 0]` (eq. 6.14): the position is measured.
    pub fn H() -> SMatrix<f64, 1, 2> {
        SMatrix::<f64, 1, 2>::new(1.0, 0.0)
    }

    /// `R` (m^2).
    pub fn R(&self) -> SMatrix<f64, 1, 1> {
        SMatrix::<f64, 1, 1>::new(self.r_m2)
    }

    /// The belief before the first sample: `x0`, `diag(P0)`.
    pub fn initial(&self) -> Gaussian<2> {
        let [pp, vv] = self.p0_diag;
        Gaussian::new(SVector::<f64, 2>::from(self.x0), SMatrix::<f64, 2, 2>::new(pp, 0.0, 0.0, vv))
    }

    /// The motion over `dt_s` seconds: `F(dt)`, `Q(dt)`.
    pub fn transition(&self, dt_s: f64) -> Transition<2> {
        Transition { F: Self::F(dt_s), Q: self.Q(dt_s) }
    }

    /// A measured position `z_m` (m): `z`, `H`, `R`.
    pub fn measurement(&self, z_m: f64) -> Measurement<2, 1> {
        Measurement { z: SVector::<f64, 1>::new(z_m), H: Self::H(), R: self.R() }
    }
}

impl Default for CvParams {
    /// The thesis's `Q = diag(0.01, 0.01)` per 1/30 s step and `R = 10`,
    /// read in cm: `q_p = 3e-5 m^2/s`, `q_v = 3e-5 m^2/s^3`, `R = 1e-3 m^2`;
    /// the object starts at rest at 0 with `P0 = diag(R, (0.1 m/s)^2)`; no gate.
    fn default() -> Self {
        CvParams {
            q_position_m2_per_s: 3e-5,
            q_velocity_m2_per_s3: 3e-5,
            r_m2: 1e-3,
            x0: [0.0, 0.0],
            p0_diag: [1e-3, 1e-2],
            gate: None,
        }
    }
}
