//! The planar slip state at the scans of a hold: the grip point's
//! displacement in the contact plane and the rotation about the normal,
//! relative to the hold's first scan, with their rates.

use nalgebra::{UnitQuaternion, Vector3};
use slidetrack_core::TimeNs;
use slidetrack_session::PlanarState;

use super::contact::ContactFrame;
use super::hold::Hold;
use super::pose::PoseTrack;

/// The twist angle of `q` about the unit axis `n` (rad, in `(-pi, pi]`):
/// the rotation about `n` of the swing-twist decomposition `q = swing twist`.
pub fn twist_angle(q: &UnitQuaternion<f64>, n: &Vector3<f64>) -> f64 {
    let along = q.imag().dot(n);
    let angle = 2.0 * along.atan2(q.w);
    // atan2 of (along, w) spans (-2 pi, 2 pi]: fold into (-pi, pi].
    if angle > std::f64::consts::PI {
        angle - std::f64::consts::TAU
    } else if angle <= -std::f64::consts::PI {
        angle + std::f64::consts::TAU
    } else {
        angle
    }
}

/// Default longest gap between two marker poses the smoother used across
/// which the planar state is still written (s). Inside a longer gap the
/// pose is the constant-velocity model's guess: after a fast turn it can
/// spin through whole turns before the next pose pins it again.
pub const DEFAULT_MAX_GAP_S: f64 = 0.5;

/// True when `t` lies between two of the sorted `used` times at most
/// `max_gap_ns` apart (or on one of them).
fn covered(used: &[TimeNs], t: TimeNs, max_gap_ns: u64) -> bool {
    let after = used.partition_point(|u| *u < t);
    match (after.checked_sub(1).and_then(|i| used.get(i)), used.get(after)) {
        (_, Some(b)) if *b == t => true,
        (Some(a), Some(b)) => b.0 - a.0 <= max_gap_ns,
        _ => false,
    }
}

/// The planar state at the scans of `hold` in `track`, in `frame`, left
/// out where the marker was not seen for more than `max_gap_s` (see
/// [`DEFAULT_MAX_GAP_S`]). The rotation is the twist of the rotation since
/// the hold's start, in `(-180, 180]` degrees: an object held between two
/// fingers does not turn further.
pub fn planar_states(
    track: &PoseTrack,
    hold: &Hold,
    frame: &ContactFrame,
    max_gap_s: f64,
) -> Vec<(TimeNs, PlanarState)> {
    let (n, x, y, c) = (frame.n(), frame.x(), frame.y(), frame.origin());
    let start = &track.poses[hold.start];
    let max_gap_ns = (max_gap_s.max(0.0) * 1e9) as u64;
    let mut out = Vec::with_capacity(hold.end - hold.start);
    for k in hold.start..hold.end {
        if !covered(&track.used, track.scans[k], max_gap_ns) {
            continue;
        }
        let pose = &track.poses[k];
        let dq = pose.orientation * start.orientation.inverse();
        let dr = dq.to_rotation_matrix();
        // The object point that was at `c` at the start, and where it is now.
        let grip = dr * (c - start.position_m) + pose.position_m;
        let displacement = grip - c;
        let velocity =
            pose.velocity_m_per_s + pose.angular_velocity_rad_per_s.cross(&(grip - pose.position_m));
        let theta = twist_angle(&dq, &n);
        out.push((
            track.scans[k],
            PlanarState {
                translation_m: [displacement.dot(&x), displacement.dot(&y)],
                rotation_rad: theta,
                velocity_m_per_s: [velocity.dot(&x), velocity.dot(&y)],
                angular_velocity_rad_per_s: pose.angular_velocity_rad_per_s.dot(&n),
            },
        ));
    }
    out
}
