//! The trackers per frame at 640x480 on one core (OpenCV limited to one
//! thread): MaskUKF on real YCB-Video frames including the point cloud from
//! depth and mask (target 300 fps; thesis 52.6 fps), and ROFT on simulated
//! fast frames including DIS optical flow on the CPU (target 100 fps; thesis
//! 96.2 fps with GPU flow). Rendering and decoding are outside the timing.
//!
//! Two measurements of each: the wall-clock time per frame, and (the
//! `_cpu` benchmarks) the CPU time of the tracking thread per frame, which
//! does not count the time the thread waited for a core on a busy machine.
#![allow(clippy::unwrap_used)] // test code: a failed unwrap is a failed test

use std::hint::black_box;
use std::path::PathBuf;
use std::time::{Duration, Instant};

use criterion::{Criterion, criterion_group, criterion_main};
use slidetrack_drivers::sim::rgbd::{FastSequence, FastSequenceConfig, SimObjectKind};
use slidetrack_vision::input::{RgbdSample, RgbdSource, SimRgbd, YcbDirectory, read_meta};
use slidetrack_vision::sources::{
    Arrivals, Delayed, FrameTruth, MeasurementSource, SlowNetwork, SlowNetworkConfig,
};
use slidetrack_vision::{ObjectModel, OnlineTracker, TrackerKind, TrackerSettings, build_tracker};

fn testdata() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../shared/testdata/rgbd")
}

/// Which clock the benchmark reads.
#[derive(Clone, Copy)]
enum Clock {
    Wall,
    ThreadCpu,
}

fn now(clock: Clock) -> Duration {
    match clock {
        Clock::Wall => {
            static START: std::sync::OnceLock<Instant> = std::sync::OnceLock::new();
            START.get_or_init(Instant::now).elapsed()
        }
        Clock::ThreadCpu => {
            let t = nix::time::clock_gettime(nix::time::ClockId::CLOCK_THREAD_CPUTIME_ID).unwrap();
            Duration::new(t.tv_sec() as u64, t.tv_nsec() as u32)
        }
    }
}

/// Runs `frames` through trackers made by `make`, `iters` frames in all,
/// timing only `process`.
fn run(
    frames: &[(RgbdSample, Arrivals)],
    make: &dyn Fn() -> Box<dyn OnlineTracker>,
    iters: u64,
    clock: Clock,
) -> Duration {
    let mut busy = Duration::ZERO;
    let mut tracker = make();
    for i in 0..iters as usize {
        let k = i % frames.len();
        if k == 0 && i > 0 {
            tracker = make();
        }
        let (sample, arrivals) = &frames[k];
        let start = now(clock);
        black_box(tracker.process(&sample.frame, arrivals).unwrap());
        busy += now(clock).saturating_sub(start);
    }
    busy
}

fn maskukf(c: &mut Criterion) {
    let dir = testdata().join("ycbv-0000/data/0000");
    let class = 8; // 009_gelatin_box
    let meta = read_meta(&dir.join("000001-meta.mat")).unwrap();
    let model = ObjectModel::load(&testdata().join("ycbv-models/009_gelatin_box/points.xyz"), 1.0).unwrap();
    let mut source = YcbDirectory::open(&dir, class, None).unwrap();
    let intrinsics = source.intrinsics().clone();
    let mut frames = Vec::new();
    while let Some(s) = source.next_frame().unwrap() {
        let mask = s.truth_mask.clone().unwrap();
        let arrivals = Arrivals {
            masks: vec![Delayed { frame_t: s.frame.t, arrival_t: s.frame.t, value: mask }],
            poses: vec![],
        };
        frames.push((s, arrivals));
    }
    let settings = TrackerSettings { initial_pose: meta.pose_of(class), ..TrackerSettings::default() };
    let make = || build_tracker(TrackerKind::MaskUkf, &model, &intrinsics, &settings).unwrap();
    c.bench_function("maskukf_frame_ycb_vga", |b| {
        b.iter_custom(|iters| run(&frames, &make, iters, Clock::Wall))
    });
    c.bench_function("maskukf_frame_ycb_vga_cpu", |b| {
        b.iter_custom(|iters| run(&frames, &make, iters, Clock::ThreadCpu))
    });
}

fn roft(c: &mut Criterion) {
    let config = FastSequenceConfig::new(SimObjectKind::CrackerBox, 2.0, 3);
    let sequence = FastSequence::new(config).unwrap();
    let model = ObjectModel::from_mesh("cracker_box", sequence.mesh().clone());
    let intrinsics = sequence.intrinsics().clone();
    let mut source = SimRgbd::new(sequence);
    let mut network = SlowNetwork::new(SlowNetworkConfig::default());
    let mut frames = Vec::new();
    while let Some(s) = source.next_frame().unwrap() {
        let (truth, mask) = (s.truth.unwrap(), s.truth_mask.clone().unwrap());
        let arrivals = network
            .on_frame(
                s.frame.t,
                Some(FrameTruth { camera_from_object: &truth.camera_from_object, mask: &mask }),
            )
            .unwrap();
        frames.push((s, arrivals));
    }
    let make = || build_tracker(TrackerKind::Roft, &model, &intrinsics, &TrackerSettings::default()).unwrap();
    c.bench_function("roft_frame_sim_vga_with_dis_flow", |b| {
        b.iter_custom(|iters| run(&frames, &make, iters, Clock::Wall))
    });
    c.bench_function("roft_frame_sim_vga_with_dis_flow_cpu", |b| {
        b.iter_custom(|iters| run(&frames, &make, iters, Clock::ThreadCpu))
    });
}

fn one_core(c: &mut Criterion) {
    opencv::core::set_num_threads(1).unwrap();
    maskukf(c);
    roft(c);
}

criterion_group!(benches, one_core);
criterion_main!(benches);
