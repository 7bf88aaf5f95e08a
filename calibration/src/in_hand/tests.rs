//! The in-hand geometry against closed forms: the twist angle, the planar
//! state of a known pivoting motion, the contact frame of known motions,
//! the hold, and the gaps left out.

use nalgebra::{SMatrix, Unit, UnitQuaternion, Vector3};
use slidetrack_core::TimeNs;
use slidetrack_estimators::pose_smoother::SmoothedPose;

use super::contact::estimate_contact_frame;
use super::hold::{HoldInputs, HoldOptions, find_hold};
use super::planar::{planar_states, twist_angle};
use super::{ContactFrame, Hold, PoseTrack};

const DT_NS: u64 = 25_000_000;

/// A pose track of an object pivoting by `theta(t)` about the axis `n`
/// through `pivot`, while `pivot` itself moves by `shift(t)`.
fn pivoting(
    n: Vector3<f64>,
    pivot: Vector3<f64>,
    marker_at_start: Vector3<f64>,
    steps: usize,
    theta: impl Fn(f64) -> f64,
    shift: impl Fn(f64) -> Vector3<f64>,
) -> PoseTrack {
    let axis = Unit::new_normalize(n);
    let start_orientation = UnitQuaternion::from_euler_angles(0.3, -0.2, 0.1);
    let (mut scans, mut poses) = (Vec::new(), Vec::new());
    for k in 0..steps {
        let t = k as f64 * DT_NS as f64 * 1e-9;
        let dq = UnitQuaternion::from_axis_angle(&axis, theta(t));
        // x -> dR (x - pivot) + pivot + shift(t).
        let position = dq * (marker_at_start - pivot) + pivot + shift(t);
        let h = 1e-5;
        let w = (theta(t + h) - theta(t - h)) / (2.0 * h);
        let velocity = axis.into_inner().cross(&(position - pivot - shift(t))) * w
            + (shift(t + h) - shift(t - h)) / (2.0 * h);
        scans.push(TimeNs(k as u64 * DT_NS));
        poses.push(SmoothedPose {
            t_s: t,
            position_m: position,
            velocity_m_per_s: velocity,
            orientation: dq * start_orientation,
            angular_velocity_rad_per_s: axis.into_inner() * w,
            covariance: SMatrix::<f64, 12, 12>::zeros(),
        });
    }
    let used = scans.clone();
    PoseTrack {
        hand_from_camera: nalgebra::Isometry3::identity(),
        scans,
        poses,
        measured: steps,
        rejected: 0,
        used,
        log_likelihood: 0.0,
    }
}

#[test]
fn the_twist_angle_is_the_rotation_about_the_axis_and_ignores_the_swing() {
    let n = Vector3::new(1.0, 0.2, -0.1).normalize();
    let perpendicular = n.cross(&Vector3::z()).normalize();
    for theta in [-3.0, -1.2, -0.1, 0.0, 0.4, 2.9] {
        let twist = UnitQuaternion::from_axis_angle(&Unit::new_normalize(n), theta);
        assert!((twist_angle(&twist, &n) - theta).abs() < 1e-12, "{theta}");
        // A swing about a perpendicular axis after the twist changes nothing.
        let swing = UnitQuaternion::from_axis_angle(&Unit::new_normalize(perpendicular), 0.7);
        assert!((twist_angle(&(swing * twist), &n) - theta).abs() < 1e-12, "swing then twist {theta}");
        // Both signs of the quaternion are the same rotation.
        let negated = UnitQuaternion::new_unchecked(-twist.into_inner());
        assert!((twist_angle(&negated, &n) - theta).abs() < 1e-12, "-q {theta}");
    }
    let swing_only = UnitQuaternion::from_axis_angle(&Unit::new_normalize(perpendicular), 1.3);
    assert!(twist_angle(&swing_only, &n).abs() < 1e-12);
}

fn frame(n: Vector3<f64>, x: Vector3<f64>, origin: Vector3<f64>) -> ContactFrame {
    ContactFrame::new(n, x, origin, "test".into()).expect("a frame")
}

/// A pivot about the grip point is pure rotation (no translation); a
/// pivot about another point translates the grip point by the closed-form
/// arc; a slide translates it by the shift.
#[test]
fn the_planar_state_of_a_known_motion_is_its_closed_form() {
    let n = Vector3::x();
    let c = Vector3::new(0.01, 0.0, 0.2);
    let marker = Vector3::new(0.012, 0.03, 0.19);
    let theta = |t: f64| 0.5 * (1.0 - (3.0 * t).cos());
    let hold = Hold { start: 0, end: 80, how: String::new() };
    let f = frame(n, Vector3::y(), c);
    // Pivot about the grip point: no translation, rotation theta.
    let track = pivoting(n, c, marker, 80, theta, |_| Vector3::zeros());
    for (k, (_, s)) in planar_states(&track, &hold, &f, 0.5).iter().enumerate() {
        let t = k as f64 * 0.025;
        assert!(s.translation_m[0].abs() < 1e-12 && s.translation_m[1].abs() < 1e-12, "{s:?}");
        assert!((s.rotation_rad - theta(t)).abs() < 1e-9, "{s:?} vs {}", theta(t));
        assert!((s.angular_velocity_rad_per_s - 1.5 * (3.0 * t).sin()).abs() < 1e-6);
        assert!(s.velocity_m_per_s[0].abs() < 1e-6 && s.velocity_m_per_s[1].abs() < 1e-6, "{s:?}");
    }
    // Pivot about a point 2 cm along y from the grip point: the grip point
    // moves on a circle of radius 2 cm about it.
    let pivot = c + Vector3::new(0.0, 0.02, 0.0);
    let track = pivoting(n, pivot, marker, 80, theta, |_| Vector3::zeros());
    // The frame: x along the hand's y, y = n x x along the hand's z.
    for (k, (_, s)) in planar_states(&track, &hold, &f, 0.5).iter().enumerate() {
        let th = theta(k as f64 * 0.025);
        // c - pivot = (0, -0.02, 0) turns about x by th: the grip point
        // moves by (0, 0.02 (1 - cos th), -0.02 sin th).
        let want = [0.02 * (1.0 - th.cos()), -0.02 * th.sin()];
        assert!((s.translation_m[0] - want[0]).abs() < 1e-12, "{s:?} vs {want:?}");
        assert!((s.translation_m[1] - want[1]).abs() < 1e-12, "{s:?} vs {want:?}");
    }
    // A slide along the frame's x axis without rotation.
    let track = pivoting(n, c, marker, 80, |_| 0.0, |t| Vector3::y() * (0.01 * t));
    let states = planar_states(&track, &hold, &f, 0.5);
    let (_, last) = states[states.len() - 1];
    assert!(
        (last.translation_m[0] - 0.01 * 79.0 * 0.025).abs() < 1e-12 && last.translation_m[1].abs() < 1e-12
    );
    assert!((last.velocity_m_per_s[0] - 0.01).abs() < 1e-6);
}

/// The normal, the pivot and the slip direction of synthetic holds come
/// back; the normal's sign follows the hint.
#[test]
fn the_contact_frame_of_known_motions_comes_back() {
    let n = Vector3::new(0.98, -0.05, 0.19).normalize();
    let c = Vector3::new(0.01, 0.003, 0.217);
    let slip = n.cross(&Vector3::z()).normalize();
    // Three holds pivot about c; one slips along `slip` without turning
    // (a slip while pivoting would bias the least-squares pivot: it is the
    // point that moves least, not a point that does not move).
    let mut tracks: Vec<PoseTrack> = (0..3)
        .map(|i| {
            let marker = c + Vector3::new(0.0, 0.02 + 0.005 * i as f64, -0.01);
            let amplitude = 0.2 + 0.1 * i as f64;
            pivoting(n, c, marker, 60, move |t| amplitude * (2.0 * t).sin(), |_| Vector3::zeros())
        })
        .collect();
    tracks.push(pivoting(n, c, c + Vector3::y() * 0.03, 60, |_| 0.0, move |t| slip * 0.004 * t));
    let hold = Hold { start: 0, end: 60, how: String::new() };
    let holds: Vec<(&PoseTrack, &Hold)> = tracks.iter().map(|t| (t, &hold)).collect();
    let f = estimate_contact_frame(&holds, Vector3::x(), Vector3::y()).expect("a frame");
    assert!((f.n() - n).norm() < 1e-6, "normal {:?} vs {n:?}", f.normal);
    // The pivot: exact in the plane (along n it is placed at the mean start).
    let d = f.origin() - c;
    assert!((d - n * n.dot(&d)).norm() < 1e-5, "origin {:?} vs {c:?}", f.origin_m);
    assert!((f.x() - slip).norm() < 1e-4, "x {:?} vs {slip:?}", f.x_axis);
    // The opposite hint flips the normal.
    let flipped = estimate_contact_frame(&holds, -Vector3::x(), Vector3::y()).expect("a frame");
    assert!((flipped.n() + n).norm() < 1e-6);
    // Without rotation the normal is the hint.
    let still = pivoting(n, c, c + Vector3::y() * 0.02, 40, |_| 0.0, |t| slip * 0.01 * t);
    let h = Hold { start: 0, end: 40, how: String::new() };
    let f = estimate_contact_frame(&[(&still, &h)], Vector3::x(), Vector3::y()).expect("a frame");
    assert_eq!(f.normal, [1.0, 0.0, 0.0]);
    assert!(f.how.contains("the hint"), "{}", f.how);
}

#[test]
fn scans_inside_a_long_marker_gap_have_no_planar_state() {
    let mut track =
        pivoting(Vector3::x(), Vector3::zeros(), Vector3::y() * 0.02, 100, |_| 0.1, |_| Vector3::zeros());
    // No pose used between scans 30 and 70 (1 s at 25 ms).
    track.used.retain(|t| *t <= TimeNs(30 * DT_NS) || *t >= TimeNs(70 * DT_NS));
    let f = frame(Vector3::x(), Vector3::y(), Vector3::zeros());
    let hold = Hold { start: 0, end: 100, how: String::new() };
    let kept: Vec<u64> = planar_states(&track, &hold, &f, 0.5).iter().map(|(t, _)| t.0 / DT_NS).collect();
    assert_eq!(kept.len(), 100 - 39, "scans 31..=69 are left out");
    assert!(kept.contains(&30) && kept.contains(&70) && !kept.contains(&50));
    // A gap within the limit keeps every scan.
    assert_eq!(planar_states(&track, &hold, &f, 1.5).len(), 100);
}

#[test]
fn the_hold_runs_from_contact_plus_settling_to_the_drop() {
    let scans: Vec<TimeNs> = (0..200).map(|k| TimeNs(k * DT_NS)).collect();
    // Contact at scan 40 (1 s), held, lost at scan 160 (4 s).
    let loads: Vec<(TimeNs, f64)> = scans
        .iter()
        .enumerate()
        .map(|(k, t)| {
            (
                *t,
                if k < 40 {
                    100.0
                } else if k < 160 {
                    20_000.0 + 500.0 * (k as f64).sin()
                } else {
                    50.0
                },
            )
        })
        .collect();
    let inputs = HoldInputs { scans: &scans, loads: &loads, cycles: None, release: None };
    let hold = find_hold(&inputs, &HoldOptions::default()).expect("a hold");
    assert_eq!((hold.start, hold.end), (60, 160), "{}", hold.how);
    // Protocol sessions: the cycles to the release, whatever the loads.
    let inputs = HoldInputs {
        scans: &scans,
        loads: &[],
        cycles: Some(TimeNs(10 * DT_NS)),
        release: Some(TimeNs(150 * DT_NS)),
    };
    let hold = find_hold(&inputs, &HoldOptions::default()).expect("a hold");
    assert_eq!((hold.start, hold.end), (10, 150));
    // No contact: no hold.
    let light: Vec<(TimeNs, f64)> = scans.iter().map(|t| (*t, 10.0)).collect();
    let inputs = HoldInputs { scans: &scans, loads: &light, cycles: None, release: None };
    assert!(find_hold(&inputs, &HoldOptions::default()).is_none());
}
