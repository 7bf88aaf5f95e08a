//! The forward pass: the constant-velocity Kalman filter of the translation
//! (three axes sharing one 2x2 covariance) and the error-state EKF of the
//! orientation, gated together on the 6-D pose innovation. The model and its
//! matrices are in the module documentation of [`super`].
#![expect(non_snake_case, reason = "matrices are named as in the thesis's equations (F, H, Q, R, P, K, S)")]

use nalgebra::{Matrix2, Matrix3, Matrix6, RowVector2, RowVector3, SMatrix, UnitQuaternion, Vector3};

use super::so3::left_jacobian;
use super::types::{PoseMeasurement, PoseSample, PoseSmootherParams, SmoothedPose};
use crate::EstimatorError;
use crate::orientation::quaternion::{exp, ominus};
use crate::rts::{Gate, GateState, MeasurementUse};

/// `ln(2 pi)`.
const LN_2PI: f64 = 1.837_877_066_409_345_5;

/// The belief at one sample: the translation's mean and covariance, the
/// orientation's nominal state and the covariance of its error.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Belief {
    /// Rows: position (m), velocity (m/s); columns: the axes x, y, z.
    pub(super) translation: SMatrix<f64, 2, 3>,
    /// Covariance of one axis's `(p, v)`; the translation's is this ⊗ I3.
    pub(super) P_translation: Matrix2<f64>,
    /// Nominal `frame_from_object`.
    pub(super) orientation: UnitQuaternion<f64>,
    /// Nominal angular velocity, measurement frame (rad/s).
    pub(super) angular_velocity: Vector3<f64>,
    /// Covariance of the error `(dtheta (rad), domega (rad/s))`.
    pub(super) P_rotation: Matrix6<f64>,
}

impl Belief {
    /// The prior at the first measured sample: its pose, at rest, `P0`.
    fn initial(params: &PoseSmootherParams, z: &PoseMeasurement) -> Belief {
        let mut translation = SMatrix::<f64, 2, 3>::zeros();
        translation.set_row(0, &z.position_m.transpose());
        Belief {
            translation,
            P_translation: params.P0_translation(),
            orientation: z.orientation,
            angular_velocity: Vector3::zeros(),
            P_rotation: params.P0_rotation(),
        }
    }

    /// The estimate at `t_s`, with the 12x12 covariance in the order
    /// `(dp, dv, dtheta, domega)`.
    pub(super) fn estimate(&self, t_s: f64) -> SmoothedPose {
        let mut covariance = SMatrix::<f64, 12, 12>::zeros();
        for (a, b, i) in translation_entries() {
            covariance[(3 * a + i, 3 * b + i)] = self.P_translation[(a, b)];
        }
        covariance.fixed_view_mut::<6, 6>(6, 6).copy_from(&self.P_rotation);
        SmoothedPose {
            t_s,
            position_m: self.translation.row(0).transpose(),
            velocity_m_per_s: self.translation.row(1).transpose(),
            orientation: self.orientation,
            angular_velocity_rad_per_s: self.angular_velocity,
            covariance,
        }
    }
}

/// `(a, b, i)` for the blocks `a, b` of `(p, v)` and the axes `i`.
fn translation_entries() -> impl Iterator<Item = (usize, usize, usize)> {
    (0..2).flat_map(|a| (0..2).flat_map(move |b| (0..3).map(move |i| (a, b, i))))
}

impl PoseSmootherParams {
    /// `F(dt)` of the translation, per axis (eq. 6.13), acting on `(p, v)`.
    #[rustfmt::skip]
    pub fn F_translation(dt_s: f64) -> Matrix2<f64> {
        Matrix2::new(
            1.0, dt_s,
            0.0, 1.0,
        )
    }

    /// `Q(dt) = diag(q_p, q_v) dt` of the translation, per axis (m^2, m^2/s^2).
    pub fn Q_translation(&self, dt_s: f64) -> Matrix2<f64> {
        Matrix2::new(self.q_position_m2_per_s * dt_s, 0.0, 0.0, self.q_velocity_m2_per_s3 * dt_s)
    }

    /// `H = [1, 0]` of the translation, per axis.
    pub fn H_translation() -> RowVector2<f64> {
        RowVector2::new(1.0, 0.0)
    }

    /// `F(omega, dt) = [[Exp(omega dt), J_l(omega dt) dt], [0, I]]` of the
    /// orientation error `(dtheta, domega)`, linearised at the nominal
    /// angular velocity `omega` (rad/s).
    pub fn F_rotation(omega: &Vector3<f64>, dt_s: f64) -> Matrix6<f64> {
        let phi = omega * dt_s;
        let mut F = Matrix6::identity();
        F.fixed_view_mut::<3, 3>(0, 0).copy_from(exp(&phi).to_rotation_matrix().matrix());
        F.fixed_view_mut::<3, 3>(0, 3).copy_from(&(left_jacobian(&phi) * dt_s));
        F
    }

    /// `Q(dt) = diag(q_theta I, q_omega I) dt` of the orientation error
    /// (rad^2, rad^2/s^2).
    pub fn Q_rotation(&self, dt_s: f64) -> Matrix6<f64> {
        let (qt, qw) = (self.q_orientation_rad2_per_s * dt_s, self.q_angular_velocity_rad2_per_s3 * dt_s);
        Matrix6::from_diagonal(&[qt, qt, qt, qw, qw, qw].into())
    }

    /// `H = [I, 0]` of the orientation error.
    pub fn H_rotation() -> SMatrix<f64, 3, 6> {
        SMatrix::<f64, 3, 6>::identity()
    }

    /// `R = r_theta I` (rad^2).
    pub fn R_rotation(&self) -> Matrix3<f64> {
        Matrix3::identity() * self.r_orientation_rad2
    }

    /// `P0` of one translation axis, `diag(m^2, m^2/s^2)`.
    pub fn P0_translation(&self) -> Matrix2<f64> {
        Matrix2::new(self.p0_position_m2, 0.0, 0.0, self.p0_velocity_m2_per_s2)
    }

    /// `P0` of the orientation error, `diag(rad^2 I, rad^2/s^2 I)`.
    pub fn P0_rotation(&self) -> Matrix6<f64> {
        let (pt, pw) = (self.p0_orientation_rad2, self.p0_angular_velocity_rad2_per_s2);
        Matrix6::from_diagonal(&[pt, pt, pt, pw, pw, pw].into())
    }
}

/// One step of the forward pass, as the smoother needs it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Step {
    /// The translation's `F` into this step (identity at the first).
    pub(super) F_translation: Matrix2<f64>,
    /// The orientation error's `F` into this step (identity at the first).
    pub(super) F_rotation: Matrix6<f64>,
    /// `p(x_k | z_1:k-1)`.
    pub(super) prior: Belief,
    /// `p(x_k | z_1:k)`.
    pub(super) posterior: Belief,
    /// What happened to the step's measurement.
    pub(super) measurement: MeasurementUse,
}

/// What a forward pass found.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Run {
    /// The index of the first sample with a measurement, where the filter
    /// starts; `None` when there is none (and no step was visited).
    pub(super) first_measured: Option<usize>,
    /// The gated log-likelihood of the measurements (see
    /// [`log_likelihood`]).
    pub(super) log_likelihood: f64,
}

/// Filters `samples` with `gate` (not `params.gate`, so that the likelihood
/// can leave out the re-acquisition), handing every step from the first
/// measured sample on to `visit`.
pub(super) fn forward(
    params: &PoseSmootherParams,
    gate: Option<Gate>,
    samples: &[PoseSample],
    mut visit: impl FnMut(Step),
) -> Result<Run, EstimatorError> {
    check_times(samples)?;
    let Some((first, z0)) = samples.iter().enumerate().find_map(|(k, s)| s.measurement.map(|z| (k, z)))
    else {
        return Ok(Run { first_measured: None, log_likelihood: 0.0 });
    };
    let (mut gate_state, mut log_likelihood) = (GateState::default(), 0.0);
    let mut previous: Option<(f64, Belief)> = None;
    for sample in &samples[first..] {
        let (F_translation, F_rotation, prior) = match previous {
            Some((t0_s, belief)) => predict(params, &belief, sample.t_s - t0_s),
            None => (Matrix2::identity(), Matrix6::identity(), Belief::initial(params, &z0)),
        };
        let (posterior, measurement) = match sample.measurement {
            None => (prior, MeasurementUse::Missing),
            Some(z) => {
                let (posterior, used, term) = correct(params, gate, &mut gate_state, &prior, &z)?;
                log_likelihood += term;
                (posterior, used)
            }
        };
        visit(Step { F_translation, F_rotation, prior, posterior, measurement });
        previous = Some((sample.t_s, posterior));
    }
    Ok(Run { first_measured: Some(first), log_likelihood })
}

/// Fails on the first time that is not finite or not after the previous one.
fn check_times(samples: &[PoseSample]) -> Result<(), EstimatorError> {
    let mut previous = f64::NEG_INFINITY;
    for (index, s) in samples.iter().enumerate() {
        if !(s.t_s.is_finite() && s.t_s > previous) {
            return Err(EstimatorError::TimeNotIncreasing { index, t_s: s.t_s });
        }
        previous = s.t_s;
    }
    Ok(())
}

/// The prediction over `dt_s` (Algorithm 1, lines 2-3; the nominal
/// orientation moved by `Exp(omega dt)`), with the two `F` it used.
fn predict(params: &PoseSmootherParams, b: &Belief, dt_s: f64) -> (Matrix2<f64>, Matrix6<f64>, Belief) {
    let F_t = PoseSmootherParams::F_translation(dt_s);
    let F_r = PoseSmootherParams::F_rotation(&b.angular_velocity, dt_s);
    let mut orientation = exp(&(b.angular_velocity * dt_s)) * b.orientation;
    orientation.renormalize_fast();
    let prior = Belief {
        translation: F_t * b.translation,
        P_translation: symmetric(F_t * b.P_translation * F_t.transpose() + params.Q_translation(dt_s)),
        orientation,
        angular_velocity: b.angular_velocity,
        P_rotation: symmetric(F_r * b.P_rotation * F_r.transpose() + params.Q_rotation(dt_s)),
    };
    (F_t, F_r, prior)
}

/// The innovation of one marker pose against the prior.
struct PoseInnovation {
    /// `y = z_p - H x` for the three axes (m).
    y_translation: RowVector3<f64>,
    /// `S = H P H^T + r_p` of one axis (m^2).
    S_translation: f64,
    /// `y = Log(q_meas q_pred^-1)` (rad).
    y_rotation: Vector3<f64>,
    /// `S^-1` of the orientation, `S = H P H^T + R` (rad^-2).
    S_rotation_inv: Matrix3<f64>,
    /// `y^T S^-1 y` of the 6-D innovation.
    mahalanobis2: f64,
    /// `log det(2 pi S)` of the 6-D innovation covariance.
    log_det_2pi_S: f64,
}

fn innovation(
    params: &PoseSmootherParams,
    prior: &Belief,
    z: &PoseMeasurement,
) -> Result<PoseInnovation, EstimatorError> {
    let finite = z.position_m.iter().chain(z.orientation.coords.iter()).all(|v| v.is_finite());
    if !finite {
        return Err(EstimatorError::NonFiniteMeasurement);
    }
    let H_t = PoseSmootherParams::H_translation();
    let y_translation = z.position_m.transpose() - H_t * prior.translation;
    let S_translation = (H_t * prior.P_translation * H_t.transpose())[(0, 0)] + params.r_position_m2;
    if !(S_translation > 0.0 && S_translation.is_finite()) {
        return Err(EstimatorError::SingularInnovation);
    }
    // The shortest rotation from the prediction to the measurement, whatever
    // the signs of the two quaternions (the logarithm's double-cover rule).
    let y_rotation = ominus(&z.orientation, &prior.orientation);
    let H_r = PoseSmootherParams::H_rotation();
    let S_r = H_r * prior.P_rotation * H_r.transpose() + params.R_rotation();
    // 3x3: the closed-form determinant and inverse (S is symmetric, and
    // positive definite when P is; a determinant that is not is refused).
    let det_S_r = S_r.determinant();
    let S_rotation_inv =
        S_r.try_inverse().filter(|_| det_S_r > 0.0).ok_or(EstimatorError::SingularInnovation)?;
    let mahalanobis2 =
        y_translation.norm_squared() / S_translation + y_rotation.dot(&(S_rotation_inv * y_rotation));
    let log_det_2pi_S = 6.0 * LN_2PI + 3.0 * S_translation.ln() + det_S_r.ln();
    if !(mahalanobis2.is_finite() && log_det_2pi_S.is_finite()) {
        return Err(EstimatorError::SingularInnovation);
    }
    Ok(PoseInnovation {
        y_translation,
        S_translation,
        y_rotation,
        S_rotation_inv,
        mahalanobis2,
        log_det_2pi_S,
    })
}

/// The correction with marker pose `z` unless the gate rejects it: the
/// posterior, what the measurement was used for, and its log-likelihood
/// term. (Nothing fails after the gate has decided.)
fn correct(
    params: &PoseSmootherParams,
    gate: Option<Gate>,
    gate_state: &mut GateState,
    prior: &Belief,
    z: &PoseMeasurement,
) -> Result<(Belief, MeasurementUse, f64), EstimatorError> {
    let innov = innovation(params, prior, z)?;
    let mahalanobis2 = innov.mahalanobis2;
    if let Some(gate) = gate
        && !gate_state.admits(&gate, mahalanobis2)
    {
        let term = -0.5 * (innov.log_det_2pi_S + gate.max_mahalanobis2);
        return Ok((*prior, MeasurementUse::Rejected { mahalanobis2 }, term));
    }
    let term = -0.5 * (innov.log_det_2pi_S + mahalanobis2);
    Ok((update(params, prior, &innov), MeasurementUse::Accepted { mahalanobis2 }, term))
}

/// Algorithm 1, lines 4-6, with the Joseph-form covariance, for both
/// halves; the orientation error's mean moved into the nominal state.
fn update(params: &PoseSmootherParams, prior: &Belief, innov: &PoseInnovation) -> Belief {
    // Translation: K = P H^T / S, one gain for the three axes.
    let H_t = PoseSmootherParams::H_translation();
    let K_t = prior.P_translation * H_t.transpose() / innov.S_translation;
    let I_KH_t = Matrix2::identity() - K_t * H_t;
    let P_translation =
        I_KH_t * prior.P_translation * I_KH_t.transpose() + K_t * params.r_position_m2 * K_t.transpose();
    // Orientation: K = P H^T S^-1.
    let H_r = PoseSmootherParams::H_rotation();
    let K_r = prior.P_rotation * H_r.transpose() * innov.S_rotation_inv;
    let I_KH_r = Matrix6::identity() - K_r * H_r;
    let P_rotation =
        I_KH_r * prior.P_rotation * I_KH_r.transpose() + K_r * params.R_rotation() * K_r.transpose();
    let dx = K_r * innov.y_rotation;
    let dtheta = Vector3::new(dx[0], dx[1], dx[2]);
    let mut orientation = exp(&dtheta) * prior.orientation;
    orientation.renormalize_fast();
    Belief {
        translation: prior.translation + K_t * innov.y_translation,
        P_translation: symmetric(P_translation),
        orientation,
        angular_velocity: prior.angular_velocity + Vector3::new(dx[3], dx[4], dx[5]),
        P_rotation: symmetric(P_rotation),
    }
}

/// `(A + A^T) / 2`: removes the asymmetry rounding leaves.
pub(super) fn symmetric<const N: usize>(a: SMatrix<f64, N, N>) -> SMatrix<f64, N, N> {
    (a + a.transpose()) * 0.5
}

/// `log p(z_1:T)` of the marker poses of `samples` under `params`, the
/// gated robust form of [`crate::constant_velocity::tune`]: each pose adds the Gaussian
/// log-density of its 6-D innovation, a pose beyond the gate adds the term
/// at the gate's edge `-1/2 (log det(2 pi S) + d2_max)` and is not used. As
/// there, the gate's re-acquisition is left out (the likelihood is that of a
/// gate that never opens). The first pose's innovation is zero (it centres
/// the prior) and adds `-1/2 log det(2 pi (P0 + R))`. `-inf` when the filter
/// fails (a time that does not increase, a non-finite measurement, a
/// covariance that stops being positive); 0 without measurements.
pub fn log_likelihood(params: &PoseSmootherParams, samples: &[PoseSample]) -> f64 {
    let gate = params.gate.map(|g| Gate { reacquire_after: None, ..g });
    match forward(params, gate, samples, |_| ()) {
        Ok(run) if !run.log_likelihood.is_nan() => run.log_likelihood,
        _ => f64::NEG_INFINITY,
    }
}
