//! ROFT on a ray-cast box moving in 6D, with exact optical flow and a slow,
//! delayed source of masks and poses (every 6 frames, 6 frames late).

use std::sync::Arc;

use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};

use super::*;
use crate::metrics::{position_error_m, rotation_error_deg};

const HALF: [f64; 3] = [0.05, 0.04, 0.07];
const DT: f64 = 1.0 / 30.0;
const DELAY: usize = 6;

fn camera() -> Pinhole {
    Pinhole { width: 160, height: 120, fx: 150.0, fy: 150.0, cx: 80.0, cy: 60.0 }
}

fn truth(k: usize) -> Isometry3<f64> {
    let t = k as f64 * DT;
    let p = Vector3::new(0.08 * (2.0 * t).sin(), 0.05 * (3.0 * t).cos() - 0.05, 0.6 + 0.03 * t.sin());
    let q = UnitQuaternion::from_scaled_axis(Vector3::new(0.5, 1.5, -0.8) * t)
        * UnitQuaternion::from_euler_angles(0.3, 0.2, 0.1);
    Isometry3::from_parts(Translation3::from(p), q)
}

/// The ray through pixel `(u, v)` hits the box at `pose`: the hit point in
/// the object frame and its depth (m).
fn ray_cast(pose: &Isometry3<f64>, u: f64, v: f64) -> Option<(Point3<f64>, f64)> {
    let k = camera();
    let dir_c = Vector3::new((u - k.cx) / k.fx, (v - k.cy) / k.fy, 1.0);
    let inv = pose.inverse();
    let origin = inv * Point3::origin();
    let dir = inv.rotation * dir_c;
    let (mut t0, mut t1) = (0.0f64, f64::INFINITY);
    for a in 0..3 {
        if dir[a].abs() < 1e-12 {
            if origin[a].abs() > HALF[a] {
                return None;
            }
            continue;
        }
        let (ta, tb) = ((-HALF[a] - origin[a]) / dir[a], (HALF[a] - origin[a]) / dir[a]);
        t0 = t0.max(ta.min(tb));
        t1 = t1.min(ta.max(tb));
    }
    (t0 <= t1 && t0 > 0.0).then(|| (origin + dir * t0, t0))
}

struct Frame {
    depth: DepthMap,
    mask: Mask,
    /// The object point seen at each mask pixel, object frame.
    points: Vec<(u32, u32, Point3<f64>)>,
}

fn render(k: usize) -> Frame {
    let c = camera();
    let mut depth = DepthMap::invalid(c.width, c.height);
    let mut mask = Mask::empty(c.width, c.height);
    let mut points = Vec::new();
    let pose = truth(k);
    for v in 0..c.height {
        for u in 0..c.width {
            let i = (v * c.width + u) as usize;
            match ray_cast(&pose, f64::from(u), f64::from(v)) {
                Some((p, d)) => {
                    depth.depth_m[i] = d as f32;
                    mask.insert(u, v);
                    points.push((u, v, p));
                }
                None => depth.depth_m[i] = 1.2, // a wall behind
            }
        }
    }
    Frame { depth, mask, points }
}

/// Exact flow from frame `k - 1` to `k` over the whole image (zero on the wall).
fn flow(previous: &Frame, k: usize) -> SharedFlow {
    let c = camera();
    let region = PixelBox { u0: 0, v0: 0, u1: c.width, v1: c.height };
    let mut flow_px = vec![[0.0f32; 2]; (c.width * c.height) as usize];
    let pose = truth(k);
    for (u, v, p) in &previous.points {
        let q = pose * p;
        if let Some((u1, v1)) = c.project([q.x, q.y, q.z]) {
            flow_px[(v * c.width + u) as usize] = [(u1 - f64::from(*u)) as f32, (v1 - f64::from(*v)) as f32];
        }
    }
    Arc::new(FlowField { region, flow_px })
}

struct BoxRenderer;

impl DepthRenderer for BoxRenderer {
    fn render(&mut self, camera_from_object: &Isometry3<f64>, pixels: &[(u32, u32)], depth_m: &mut Vec<f32>) {
        depth_m.clear();
        depth_m.extend(pixels.iter().map(|(u, v)| {
            ray_cast(camera_from_object, f64::from(*u), f64::from(*v)).map_or(0.0, |(_, d)| d as f32)
        }));
    }
}

/// The network's pose of frame `k`: truth plus a fixed small error, and a
/// gross outlier for frame `outlier`.
fn network_pose(k: usize, outlier: Option<usize>) -> Isometry3<f64> {
    let mut p = truth(k);
    p.translation.vector += Vector3::new(0.004, -0.003, 0.005);
    if Some(k) == outlier {
        p.translation.vector += Vector3::new(0.15, 0.1, 0.0);
    }
    p
}

struct Run {
    position_errors_m: Vec<f64>,
    rotation_errors_deg: Vec<f64>,
    outliers_rejected: usize,
}

fn run(config: RoftConfig, frames: usize, outlier: Option<usize>) -> Run {
    let mut roft = Roft::new(config, camera(), Some(Box::new(BoxRenderer))).unwrap();
    let rendered: Vec<Frame> = (0..frames).map(render).collect();
    let mut out =
        Run { position_errors_m: Vec::new(), rotation_errors_deg: Vec::new(), outliers_rejected: 0 };
    for k in 0..frames {
        let t_ns = (k as f64 * DT * 1e9) as u64;
        let stamp = |j: usize| (j as f64 * DT * 1e9) as u64;
        let arrives = k >= DELAY && k % DELAY == 0;
        let mask = if k == 0 {
            Some((0, rendered[0].mask.clone()))
        } else {
            arrives.then(|| (stamp(k - DELAY), rendered[k - DELAY].mask.clone()))
        };
        let pose = arrives.then(|| (stamp(k - DELAY), network_pose(k - DELAY, outlier)));
        let input = RoftInput {
            t_ns,
            depth: Arc::new(rendered[k].depth.clone()),
            flow: (k > 0).then(|| flow(&rendered[k - 1], k)),
            mask,
            pose,
        };
        let report = roft.step(input).unwrap();
        if matches!(report.pose, PoseUse::Outlier { .. }) {
            out.outliers_rejected += 1;
        }
        if let Some(e) = roft.estimate() {
            assert!(e.is_finite());
            out.position_errors_m.push(position_error_m(&e.camera_from_object, &truth(k)));
            out.rotation_errors_deg.push(rotation_error_deg(&e.camera_from_object, &truth(k)));
        }
    }
    out
}

fn tail_max(v: &[f64], n: usize) -> f64 {
    v[v.len().saturating_sub(n)..].iter().fold(0.0, |m, x| m.max(*x))
}

#[test]
fn roft_tracks_a_fast_box_between_delayed_poses() {
    let r = run(RoftConfig::default(), 60, None);
    assert_eq!(r.position_errors_m.len(), 60 - DELAY, "initialised when the first pose arrived");
    assert!(tail_max(&r.position_errors_m, 40) < 0.025, "{:?}", r.position_errors_m);
    assert!(tail_max(&r.rotation_errors_deg, 40) < 6.0, "{:?}", r.rotation_errors_deg);
    // The last pose of the delayed network is far worse at these speeds.
    let last_network_pose = |k: usize| network_pose((k / DELAY - 1) * DELAY, None);
    let network: Vec<f64> = (DELAY..60).map(|k| position_error_m(&last_network_pose(k), &truth(k))).collect();
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    assert!(
        mean(&network) > 2.0 * mean(&r.position_errors_m),
        "{} vs {}",
        mean(&network),
        mean(&r.position_errors_m)
    );
}

#[test]
fn an_outlier_pose_is_rejected_by_the_depth_test() {
    let with = run(RoftConfig::default(), 48, Some(24));
    assert_eq!(with.outliers_rejected, 1);
    let without = run(RoftConfig { outlier_rejection: false, ..RoftConfig::default() }, 48, Some(24));
    assert_eq!(without.outliers_rejected, 0);
    assert!(tail_max(&with.position_errors_m, 18) < 0.025, "{:?}", with.position_errors_m);
    assert!(tail_max(&without.position_errors_m, 18) > 0.04, "{:?}", without.position_errors_m);
}

#[test]
fn without_velocities_the_estimate_lags() {
    let full = run(RoftConfig::default(), 48, None);
    let no_velocity = run(RoftConfig { use_velocity: false, ..RoftConfig::default() }, 48, None);
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    assert!(mean(&no_velocity.position_errors_m) > 2.0 * mean(&full.position_errors_m));
}

#[test]
fn bad_frames_are_refused_or_survived() {
    let mut roft = Roft::new(RoftConfig::default(), camera(), None).unwrap();
    let zeros = Arc::new(DepthMap::invalid(160, 120));
    let first = render(0);
    let input = |t_ns, pose| RoftInput {
        t_ns,
        depth: zeros.clone(),
        flow: None,
        mask: Some((t_ns, first.mask.clone())),
        pose,
    };
    roft.step(input(10, Some((10, truth(0))))).unwrap();
    assert!(matches!(roft.step(input(10, None)), Err(RoftError::OutOfOrder { .. })));
    let wrong = RoftInput {
        t_ns: 20,
        depth: Arc::new(DepthMap::invalid(10, 10)),
        flow: None,
        mask: None,
        pose: None,
    };
    assert!(matches!(roft.step(wrong), Err(RoftError::DepthSize { .. })));
    // A depth of zeros everywhere, an empty mask and a NaN pose: no NaN.
    let nan_pose = Isometry3::from_parts(Translation3::new(f64::NAN, 0.0, 0.0), UnitQuaternion::identity());
    let report = roft
        .step(RoftInput {
            t_ns: 30,
            depth: zeros.clone(),
            flow: Some(flow(&first, 1)),
            mask: Some((30, Mask::empty(160, 120))),
            pose: Some((30, nan_pose)),
        })
        .unwrap();
    assert_eq!(report.pose, PoseUse::Invalid);
    assert_eq!(report.mask, DelayedMaskUse::Unusable);
    assert!(roft.estimate().unwrap().is_finite());
    let bad_camera = Pinhole { fx: 0.0, ..camera() };
    assert!(Roft::new(RoftConfig::default(), bad_camera, None).is_err());
}
