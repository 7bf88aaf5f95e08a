//! Ground-truth smoothing speed: 100 sessions of 60 s of tactile scans at
//! 100 Hz (6000 steps each, a marker position at every third step) through
//! the constant-velocity Kalman filter and RTS smoother. Target: under 1 s
//! in all (the thesis's smoothing took 52 s for its data, Sec. 6.3.7).
//!
//! `cargo bench -p slidetrack-estimators --bench rts`

use std::hint::black_box;
use std::time::{Duration, Instant};

use criterion::{Criterion, criterion_group};
use slidetrack_estimators::constant_velocity::{CvParams, CvSample};
use slidetrack_estimators::rts::Gate;

const SESSIONS: usize = 100;
const STEPS: usize = 6000;

/// One session: a slow slide with a small deterministic wobble as measurement noise.
fn session(seed: usize) -> Vec<CvSample> {
    (0..STEPS)
        .map(|k| {
            let t_s = k as f64 * 0.01;
            let wobble = ((k * 7919 + seed * 104_729) % 1000) as f64 * 1e-7 - 5e-5;
            CvSample { t_s, z_m: (k % 3 == 0).then_some(0.002 * t_s + wobble) }
        })
        .collect()
}

fn smooth_all(params: &CvParams, sessions: &[Vec<CvSample>]) -> f64 {
    sessions
        .iter()
        .map(|s| params.smooth(s).map_or(f64::NAN, |track| track.smoothed[STEPS / 2].mean[0]))
        .sum()
}

fn bench(c: &mut Criterion) {
    let sessions: Vec<Vec<CvSample>> = (0..SESSIONS).map(session).collect();
    let params = CvParams { gate: Some(Gate::at(25.0)), ..CvParams::default() };
    let mut group = c.benchmark_group("ground_truth");
    group.sample_size(10).measurement_time(Duration::from_secs(8));
    group.bench_function("smooth 100 sessions x 6000 steps", |b| {
        b.iter(|| smooth_all(&params, black_box(&sessions)))
    });
    group.finish();

    // The figure against the target, as a median of 7 plain runs.
    let mut times: Vec<f64> = (0..7)
        .map(|_| {
            let start = Instant::now();
            black_box(smooth_all(&params, black_box(&sessions)));
            start.elapsed().as_secs_f64()
        })
        .collect();
    times.sort_by(f64::total_cmp);
    let median = times[times.len() / 2];
    let verdict = if median < 1.0 { "meets" } else { "MISSES" };
    println!(
        "smoothing {SESSIONS} sessions x {STEPS} steps: median {:.1} ms ({:.2} us per step); {verdict} the 1 s target",
        median * 1e3,
        median / (SESSIONS * STEPS) as f64 * 1e6
    );
}

criterion_group!(benches, bench);

fn main() {
    benches();
    Criterion::default().configure_from_args().final_summary();
}
