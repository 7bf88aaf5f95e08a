//! The contact frame of a parallel gripper, from the held objects' motion.
//!
//! For the scans `k` of a hold starting at `s`, the motion since the start
//! is `x -> dR_k x + dp_k` with `dR_k = R_k R_s^T`, `dp_k = p_k - dR_k p_s`
//! (`R`, `p`: the object's smoothed pose in the hand).
//! - **Normal** `n`: the principal eigenvector of `sum r_k r_k^T` over every
//!   scan of every hold, `r_k = Log(dR_k)` the rotation vector: the axis
//!   that carries most of the rotation (on a parallel gripper the objects
//!   pivot about the closing axis). Its sign: `n . n_hint >= 0`.
//! - **Origin** `c`, the grip point: the point of the hand that moves least
//!   with the objects, `min sum |(dR_k - I) c + dp_k|^2`, sought in the plane
//!   through the mean start position perpendicular to `n` (along `n` a
//!   rotation about `n` cannot place it).
//! - **x axis**: the principal direction of the grip point's displacements
//!   `(dR_k - I) c + dp_k` projected on the plane, signed so that their sum
//!   is not negative along it (the direction the objects mostly slip in);
//!   `y = n x x`.
//!
//! With too little rotation to define an axis (RMS angle below
//! [`MIN_RMS_ROTATION_RAD`]) the normal is `n_hint` and the origin the mean
//! start position; with too little displacement the x axis is the hint's
//! projection.

use nalgebra::{Matrix2, Matrix3, SymmetricEigen, Vector2, Vector3};
use serde::{Deserialize, Serialize};

use super::hold::Hold;
use super::pose::PoseTrack;

/// Least RMS rotation of the holds (rad) from which the normal and the grip
/// point are estimated from the rotations (0.5 deg).
pub const MIN_RMS_ROTATION_RAD: f64 = 0.5 * std::f64::consts::PI / 180.0;

/// Least RMS in-plane displacement (m) from which the x axis is estimated.
pub const MIN_RMS_DISPLACEMENT_M: f64 = 1e-4;

/// The contact frame in the hand frame: `z` (the normal) along the closing
/// axis, `x` and `y` in the contact plane, origin at the grip point.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ContactFrame {
    /// Unit normal (the closing axis) in the hand frame.
    pub normal: [f64; 3],
    /// Unit x axis in the contact plane, in the hand frame.
    pub x_axis: [f64; 3],
    /// The grip point in the hand frame (m).
    pub origin_m: [f64; 3],
    /// How it was found, in words.
    pub how: String,
}

impl ContactFrame {
    /// The normal as a vector.
    pub fn n(&self) -> Vector3<f64> {
        Vector3::from(self.normal)
    }

    /// The x axis as a vector.
    pub fn x(&self) -> Vector3<f64> {
        Vector3::from(self.x_axis)
    }

    /// `y = n x x`.
    pub fn y(&self) -> Vector3<f64> {
        self.n().cross(&self.x())
    }

    /// The origin as a vector (m).
    pub fn origin(&self) -> Vector3<f64> {
        Vector3::from(self.origin_m)
    }

    /// A frame with `normal` and `x_axis` made orthonormal (`x` projected on
    /// the plane); `None` when they are parallel or not finite.
    pub fn new(
        normal: Vector3<f64>,
        x_hint: Vector3<f64>,
        origin_m: Vector3<f64>,
        how: String,
    ) -> Option<ContactFrame> {
        let n = normal.try_normalize(1e-9)?;
        let x = (x_hint - n * n.dot(&x_hint)).try_normalize(1e-9)?;
        let ok = n.iter().chain(x.iter()).chain(origin_m.iter()).all(|v| v.is_finite());
        ok.then(|| ContactFrame { normal: n.into(), x_axis: x.into(), origin_m: origin_m.into(), how })
    }
}

/// The relative motions `(dR_k as a rotation vector, dR_k, dp_k)` of the
/// holds' scans, and the mean start position.
struct Motions {
    rotations: Vec<(Vector3<f64>, Matrix3<f64>, Vector3<f64>)>,
    start_mean: Vector3<f64>,
}

fn motions(holds: &[(&PoseTrack, &Hold)]) -> Motions {
    let mut rotations = Vec::new();
    let mut start_sum = Vector3::zeros();
    for (track, hold) in holds {
        let s = &track.poses[hold.start];
        start_sum += s.position_m;
        for k in &track.poses[hold.start..hold.end] {
            let dq = k.orientation * s.orientation.inverse();
            let dr = dq.to_rotation_matrix().into_inner();
            rotations.push((dq.scaled_axis(), dr, k.position_m - dr * s.position_m));
        }
    }
    Motions { rotations, start_mean: start_sum / holds.len().max(1) as f64 }
}

/// The principal eigenvector of a symmetric matrix.
fn principal(m: &Matrix3<f64>) -> (Vector3<f64>, f64) {
    let e = SymmetricEigen::new(*m);
    let i = e.eigenvalues.imax();
    (e.eigenvectors.column(i).into_owned(), e.eigenvalues[i])
}

/// Two unit vectors spanning the plane perpendicular to `n`.
fn plane_basis(n: &Vector3<f64>) -> [Vector3<f64>; 2] {
    let helper = if n.x.abs() < 0.9 { Vector3::x() } else { Vector3::y() };
    let a = (helper - n * n.dot(&helper)).normalize();
    [a, n.cross(&a)]
}

/// The contact frame of the motions of `holds` (see the module
/// documentation); `n_hint` signs the normal and replaces it without
/// rotation, `x_hint` replaces the x axis without displacement.
pub fn estimate_contact_frame(
    holds: &[(&PoseTrack, &Hold)],
    n_hint: Vector3<f64>,
    x_hint: Vector3<f64>,
) -> Option<ContactFrame> {
    let m = motions(holds);
    let count = m.rotations.len().max(1) as f64;
    let scatter: Matrix3<f64> = m.rotations.iter().map(|(r, _, _)| r * r.transpose()).sum();
    let rms_angle = (scatter.trace() / count).sqrt();
    let rotates = rms_angle >= MIN_RMS_ROTATION_RAD;
    let (n, origin, normal_how) = if rotates {
        let (axis, top) = principal(&scatter);
        let n = if axis.dot(&n_hint) < 0.0 { -axis } else { axis };
        let origin = grip_point(&m, &n).unwrap_or(m.start_mean);
        let how = format!(
            "normal: the principal axis of the rotations relative to each hold's start ({:.1} % of their \
             scatter, RMS angle {:.2} deg over {} scans of {} holds); origin: the least-squares pivot point",
            100.0 * top / scatter.trace().max(1e-300),
            rms_angle.to_degrees(),
            m.rotations.len(),
            holds.len()
        );
        (n, origin, how)
    } else {
        let how = format!(
            "normal: the hint {:?} (RMS rotation {:.2} deg over {} scans, too little to find an axis); origin: \
             the mean position of the marker at the holds' start",
            [n_hint.x, n_hint.y, n_hint.z],
            rms_angle.to_degrees(),
            m.rotations.len()
        );
        (n_hint.try_normalize(1e-9)?, m.start_mean, how)
    };
    let (x, x_how) =
        x_axis(&m, &n, &origin).unwrap_or((x_hint, "x axis: the hint, projected on the plane".into()));
    ContactFrame::new(n, x, origin, format!("estimated from the held motion: {normal_how}; {x_how}"))
}

/// The least-squares pivot point in the plane through the mean start
/// position perpendicular to `n`.
fn grip_point(m: &Motions, n: &Vector3<f64>) -> Option<Vector3<f64>> {
    let [a, b] = plane_basis(n);
    let (mut ata, mut atb) = (Matrix2::<f64>::zeros(), Vector2::<f64>::zeros());
    for (_, dr, dp) in &m.rotations {
        let d = dr - Matrix3::identity();
        let cols = [d * a, d * b];
        let rhs = -(d * m.start_mean + dp);
        for i in 0..2 {
            atb[i] += cols[i].dot(&rhs);
            for j in 0..2 {
                ata[(i, j)] += cols[i].dot(&cols[j]);
            }
        }
    }
    let u = ata.try_inverse()? * atb;
    Some(m.start_mean + a * u[0] + b * u[1])
}

/// The principal direction of the grip point's in-plane displacements.
fn x_axis(m: &Motions, n: &Vector3<f64>, c: &Vector3<f64>) -> Option<(Vector3<f64>, String)> {
    let (mut scatter, mut sum) = (Matrix3::zeros(), Vector3::zeros());
    for (_, dr, dp) in &m.rotations {
        let d = (dr - Matrix3::identity()) * c + dp;
        let d = d - n * n.dot(&d);
        scatter += d * d.transpose();
        sum += d;
    }
    let rms = (scatter.trace() / m.rotations.len().max(1) as f64).sqrt();
    if rms < MIN_RMS_DISPLACEMENT_M {
        return None;
    }
    let (axis, top) = principal(&scatter);
    let x = if axis.dot(&sum) < 0.0 { -axis } else { axis };
    let how = format!(
        "x axis: the principal direction of the grip point's displacements in the plane ({:.1} % of their \
         scatter, RMS {:.2} mm), towards their mean",
        100.0 * top / scatter.trace().max(1e-300),
        rms * 1e3
    );
    Some((x, how))
}
