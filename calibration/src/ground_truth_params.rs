//! The default smoother parameters of the ground truth, and their record in
//! the channel metadata.

use slidetrack_estimators::constant_velocity::CvParams;
use slidetrack_estimators::rts::Gate;
use slidetrack_session::GroundTruthParameters;

use super::measurements::Measurements;

/// Default innovation gate: squared Mahalanobis distance 25, i.e. a marker
/// position more than 5 standard deviations of the innovation away from the
/// prediction is an outlier (chi-square, 1 degree of freedom: 6e-7 false alarms).
pub const DEFAULT_GATE_MAHALANOBIS2: f64 = 25.0;

/// Default marker noise: 0.5 mm standard deviation along the axis (m^2).
pub const DEFAULT_R_M2: f64 = 2.5e-7;
/// Default position random walk: 0.1 mm per square-root second (m^2/s).
pub const DEFAULT_Q_POSITION_M2_PER_S: f64 = 1e-8;
/// Default velocity random walk: 10 mm/s per square-root second (m^2/s^3),
/// the scale of the velocity changes of a stick-slip episode.
pub const DEFAULT_Q_VELOCITY_M2_PER_S3: f64 = 1e-4;

/// The default parameters of the labelling (see `docs/ground-truth.md`
/// for how they relate to the thesis's `Q = diag(0.01, 0.01)`, `R = 10`,
/// which [`CvParams::default`] holds): `R` is a marker noise of
/// 0.5 mm, `Q(dt) = diag(1e-8 m^2/s, 1e-4 m^2/s^3) dt`, the object starts at
/// rest at 0 with `P0 = diag(R, (10 mm/s)^2)`, and the gate rejects marker
/// positions beyond 5 standard deviations of the innovation.
pub fn default_params() -> CvParams {
    CvParams {
        q_position_m2_per_s: DEFAULT_Q_POSITION_M2_PER_S,
        q_velocity_m2_per_s3: DEFAULT_Q_VELOCITY_M2_PER_S3,
        r_m2: DEFAULT_R_M2,
        x0: [0.0, 0.0],
        p0_diag: [DEFAULT_R_M2, 1e-4],
        gate: gate(Some(DEFAULT_GATE_MAHALANOBIS2)),
    }
}

/// The thesis's parameters exactly: `Q = diag(0.01, 0.01)` per 1/30 s step
/// and `R = 10`, read in cm (only their ratios matter), no gate.
pub fn thesis_params() -> CvParams {
    CvParams::default()
}

/// The metadata record of a labelling with `params` on `measurements`.
pub fn parameters_record(params: &CvParams, measurements: &Measurements) -> GroundTruthParameters {
    let [pp, vv] = params.p0_diag;
    GroundTruthParameters {
        model: "constant velocity (thesis eqs. 6.12-6.15): x = (p, v); x_k = F x_k-1 + w, F = [[1, dt], [0, 1]], \
                w ~ N(0, Q_k); z_k = p_k + nu, nu ~ N(0, R); Kalman filter (Algorithm 1, Joseph form) then \
                Rauch-Tung-Striebel smoother (Algorithm 10)"
            .into(),
        units: "position m, velocity m/s, time s; covariances in the squares of these".into(),
        sample_times: "every /tactile/raw log_time and every camera log_time with a marker position, merged and \
                       deduplicated; t = (log_time - first log_time) * 1e-9 s, dt_k = t_k - t_k-1; the ground truth \
                       is output at the /tactile/raw times; steps without a marker position only predict"
            .into(),
        process_noise: "Q_k = diag(q_position_m2_per_s, q_velocity_m2_per_s3) * dt_k; the first sample has F = I, \
                        Q = 0, starting from x0, p0"
            .into(),
        q_position_m2_per_s: params.q_position_m2_per_s,
        q_velocity_m2_per_s3: params.q_velocity_m2_per_s3,
        r_m2: params.r_m2,
        x0: params.x0,
        p0: [[pp, 0.0], [0.0, vv]],
        gate_max_mahalanobis2: params.gate.map(|g| g.max_mahalanobis2),
        gate_reacquire_after: params.gate.and_then(|g| g.reacquire_after),
        measurement_source: format!("{}; 0 at the first valid sample", measurements.source),
        axis_in_camera: measurements.axis_in_camera.map(|a| [a.x, a.y, a.z]),
        tuning: None,
        software_version: env!("CARGO_PKG_VERSION").into(),
    }
}

/// The smoother parameters of a metadata record (its off-diagonal initial
/// covariance, always 0 here, is ignored).
pub fn params_from_record(record: &GroundTruthParameters) -> CvParams {
    CvParams {
        q_position_m2_per_s: record.q_position_m2_per_s,
        q_velocity_m2_per_s3: record.q_velocity_m2_per_s3,
        r_m2: record.r_m2,
        x0: record.x0,
        p0_diag: [record.p0[0][0], record.p0[1][1]],
        gate: gate(record.gate_max_mahalanobis2)
            .map(|g| Gate { reacquire_after: record.gate_reacquire_after, ..g }),
    }
}

/// A gate for `max_mahalanobis2` (never re-acquiring: [`Gate`]), `None`
/// when it is not a positive number.
pub fn gate(max_mahalanobis2: Option<f64>) -> Option<Gate> {
    max_mahalanobis2.filter(|g| g.is_finite() && *g > 0.0).map(Gate::at)
}
