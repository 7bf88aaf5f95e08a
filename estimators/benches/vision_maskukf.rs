//! MaskUKF per frame at 640x480: the partial cloud of a box seen by a VGA
//! camera (about 16 000 points before subsampling), outlier rejection and
//! the sequential UKF. One thread. Target: 300 fps (thesis: 52.6 fps).
#![expect(clippy::unwrap_used, reason = "test code: a failed unwrap is a failed test")]

use std::hint::black_box;
use std::sync::Arc;

use criterion::{Criterion, criterion_group, criterion_main};
use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use slidetrack_estimators::maskukf::{CloudInput, MaskUkf, MaskUkfConfig, ObjectPoints};
use slidetrack_estimators::orientation::PoseVelocity;

const HALF: [f64; 3] = [0.08, 0.03, 0.105];

/// The box's surface points (about 2600, like the YCB-Video models).
fn model() -> Arc<ObjectPoints> {
    let mut points = Vec::new();
    let step = 0.0062;
    for axis in 0..3 {
        let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
        for sign in [-1.0, 1.0] {
            let (nu, nv) = ((2.0 * HALF[u] / step) as i32, (2.0 * HALF[v] / step) as i32);
            for i in 0..=nu {
                for j in 0..=nv {
                    let mut p = [0.0; 3];
                    p[axis] = sign * HALF[axis];
                    p[u] = -HALF[u] + f64::from(i) * step;
                    p[v] = -HALF[v] + f64::from(j) * step;
                    points.push(Point3::from(p));
                }
            }
        }
    }
    Arc::new(ObjectPoints::new(points).unwrap())
}

/// Ray-casts the box from a 640x480 camera (f = 554 px): the points of every
/// pixel that sees it, with 2 mm of noise.
fn cloud(pose: &Isometry3<f64>) -> Vec<Point3<f64>> {
    let inv = pose.inverse();
    let origin = inv * Point3::origin();
    let mut out = Vec::new();
    let mut state = 7u64;
    for v in 0..480 {
        for u in 0..640 {
            let dir = inv.rotation
                * Vector3::new((f64::from(u) - 319.5) / 554.3, (f64::from(v) - 239.5) / 554.3, 1.0);
            let (mut t0, mut t1) = (0.0f64, f64::INFINITY);
            for a in 0..3 {
                let (ta, tb) = ((-HALF[a] - origin[a]) / dir[a], (HALF[a] - origin[a]) / dir[a]);
                t0 = t0.max(ta.min(tb));
                t1 = t1.min(ta.max(tb));
            }
            if t0 <= t1 && t0 > 0.0 {
                state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                let n = ((state >> 33) as f64 / (1u64 << 31) as f64 - 0.5) * 0.004;
                out.push(pose * (origin + dir * t0) + Vector3::new(n, -n, n));
            }
        }
    }
    out
}

fn bench(c: &mut Criterion) {
    let pose = Isometry3::from_parts(
        Translation3::new(0.02, -0.01, 0.6),
        UnitQuaternion::from_euler_angles(0.4, 0.5, 0.3),
    );
    let points = cloud(&pose);
    let model = model();
    eprintln!("cloud: {} points, model: {} points", points.len(), model.len());
    let mut filter = MaskUkf::new(model, MaskUkfConfig::default(), &PoseVelocity::at_rest(pose)).unwrap();
    c.bench_function("maskukf_step_vga_box", |b| {
        b.iter(|| {
            let input = CloudInput::Cloud { points_in_camera: black_box(&points), mask_pixels: points.len() };
            black_box(filter.step(1.0 / 30.0, input).unwrap());
        })
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
