//! What the pose smoother reads and returns: the samples and their marker
//! poses, the parameters, the estimate at a sample.

use nalgebra::{SMatrix, UnitQuaternion, Vector3};

use crate::rts::Gate;

/// The default gate on the squared Mahalanobis distance of the 6-D pose
/// innovation: the chi-square quantile with 6 degrees of freedom of the tail
/// probability 5.7e-7 that the 1-D gate of 25 (5 sigma) of the marker
/// positions has, so an inlier marker pose is rejected as rarely as a
/// position is there. (The 99.9 % quantile would be 22.5; an ArUco
/// orientation flip of 30 degrees at 1 degree of noise lies in the hundreds.)
pub const POSE_GATE_MAHALANOBIS2: f64 = 39.5;

/// One sample time, with the marker pose measured there if any.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PoseSample {
    /// Time (s), strictly increasing along a sequence.
    pub t_s: f64,
    /// The measured pose, `None` for a predict-only step.
    pub measurement: Option<PoseMeasurement>,
}

/// A measured pose `frame_from_object`: where the object is in the
/// measurement frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PoseMeasurement {
    /// Position of the object origin in the measurement frame (m).
    pub position_m: Vector3<f64>,
    /// Rotation `frame_from_object` (either sign of the quaternion).
    pub orientation: UnitQuaternion<f64>,
}

/// The parameters of the pose smoother, in SI units. The densities scale
/// `Q` with the step as in [`crate::constant_velocity`]: `Q(dt) = q dt`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PoseSmootherParams {
    /// Spectral density of the position random walk, per axis, `q_p` (m^2/s).
    pub q_position_m2_per_s: f64,
    /// Spectral density of the velocity random walk, per axis, `q_v` (m^2/s^3).
    pub q_velocity_m2_per_s3: f64,
    /// Variance of one measured position coordinate, `r_p` (m^2).
    pub r_position_m2: f64,
    /// Spectral density of the orientation random walk, per tangent axis,
    /// `q_theta` (rad^2/s).
    pub q_orientation_rad2_per_s: f64,
    /// Spectral density of the angular-velocity random walk, per axis,
    /// `q_omega` (rad^2/s^3).
    pub q_angular_velocity_rad2_per_s3: f64,
    /// Variance of one measured orientation tangent coordinate, `r_theta`
    /// (rad^2; the angle error is about `sqrt(3 r_theta)`).
    pub r_orientation_rad2: f64,
    /// Initial position variance per axis (m^2).
    pub p0_position_m2: f64,
    /// Initial velocity variance per axis (m^2/s^2).
    pub p0_velocity_m2_per_s2: f64,
    /// Initial orientation variance per tangent axis (rad^2).
    pub p0_orientation_rad2: f64,
    /// Initial angular-velocity variance per axis (rad^2/s^2).
    pub p0_angular_velocity_rad2_per_s2: f64,
    /// Innovation gate on the 6-D pose innovation; `None` accepts every pose.
    pub gate: Option<Gate>,
}

impl Default for PoseSmootherParams {
    /// A marker pose noise of 1 mm and 1 degree per axis; velocity changes
    /// of 1 cm/s and angular-velocity changes of 0.3 rad/s per root second,
    /// small walks of the pose itself; a diffuse start (the measurement's
    /// variance on the pose, 0.1 m/s and 1 rad/s on the velocities); the
    /// gate at [`POSE_GATE_MAHALANOBIS2`], never re-acquiring.
    fn default() -> Self {
        let one_degree = 1f64.to_radians();
        PoseSmootherParams {
            q_position_m2_per_s: 1e-8,
            q_velocity_m2_per_s3: 1e-4,
            r_position_m2: 1e-6,
            q_orientation_rad2_per_s: 1e-5,
            q_angular_velocity_rad2_per_s3: 0.1,
            r_orientation_rad2: one_degree * one_degree,
            p0_position_m2: 1e-6,
            p0_velocity_m2_per_s2: 1e-2,
            p0_orientation_rad2: one_degree * one_degree,
            p0_angular_velocity_rad2_per_s2: 1.0,
            gate: Some(Gate::at(POSE_GATE_MAHALANOBIS2)),
        }
    }
}

/// The estimate at one sample.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SmoothedPose {
    /// Time (s).
    pub t_s: f64,
    /// Position of the object origin, measurement frame (m).
    pub position_m: Vector3<f64>,
    /// Its velocity, measurement frame (m/s).
    pub velocity_m_per_s: Vector3<f64>,
    /// Rotation `frame_from_object`. Its sign is continuous along the track,
    /// starting from the first measurement's: compare rotations, not
    /// components.
    pub orientation: UnitQuaternion<f64>,
    /// Angular velocity, measurement frame (rad/s): `q(t + dt) ≈
    /// Exp(omega dt) q(t)`.
    pub angular_velocity_rad_per_s: Vector3<f64>,
    /// Covariance of the tangent error `(dp (m), dv (m/s), dtheta (rad),
    /// domega (rad/s))`, three coordinates each in that order, with
    /// `q_true = Exp(dtheta) q` (measurement frame).
    pub covariance: SMatrix<f64, 12, 12>,
}
