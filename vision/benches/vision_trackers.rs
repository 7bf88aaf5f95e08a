//! The trackers per frame at 640x480 on one core (OpenCV limited to one
//! thread): MaskUKF on real YCB-Video frames including the point cloud from
//! depth and mask (target 300 fps; thesis 52.6 fps), and ROFT on simulated
//! fast frames including DIS optical flow on the CPU (target 100 fps; thesis
//! 96.2 fps with GPU flow). Rendering and decoding are outside the timing.
//! ROFT's flow covers the box of its mask with a 40 px margin (the only
//! pixels it uses); the flow of the whole frame is timed for comparison.
//! (The in-hand rig's whole vision step is the `vision_inhand` benchmark of
//! the experiment crate.)
//!
//! Only frames the tracker tracked are timed (ROFT's first frames, before
//! the first delayed pose arrives, are run but not timed). After criterion's
//! statistics, each benchmark prints the median time per frame and its
//! frame rate next to the target. Two measurements of each: the wall-clock
//! time per frame, and (the `_cpu` benchmarks) the CPU time of the tracking
//! thread per frame, which does not count the time the thread waited for a
//! core on a busy machine.
#![expect(clippy::unwrap_used, reason = "test code: a failed unwrap is a failed test")]

use std::hint::black_box;
use std::path::PathBuf;
use std::time::{Duration, Instant};

use criterion::{Criterion, criterion_group, criterion_main};
use slidetrack_sim::rgbd::{FastSequence, FastSequenceConfig, SimObjectKind};
use slidetrack_vision::flow::FlowConfig;
use slidetrack_vision::input::{RgbdSample, RgbdSource, YcbDirectory, read_meta};
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

/// Plays `frames` through a tracker, pass after pass (a new tracker at each
/// pass), and times `process` on the frames the tracker tracked. Frames
/// before a tracker starts (ROFT waits for the first delayed pose) cost next
/// to nothing and are run but not timed. The position is kept between
/// calls, so criterion's short samples see the whole sequence.
struct Player<'a> {
    frames: &'a [(RgbdSample, Arrivals)],
    make: &'a dyn Fn() -> Box<dyn OnlineTracker>,
    tracker: Box<dyn OnlineTracker>,
    next: usize,
}

impl<'a> Player<'a> {
    fn new(frames: &'a [(RgbdSample, Arrivals)], make: &'a dyn Fn() -> Box<dyn OnlineTracker>) -> Player<'a> {
        Player { frames, make, tracker: make(), next: 0 }
    }

    /// The time of the next tracked frame.
    fn next_tracked(&mut self, clock: Clock) -> Duration {
        loop {
            if self.next == self.frames.len() {
                self.tracker = (self.make)();
                self.next = 0;
            }
            let (sample, arrivals) = &self.frames[self.next];
            self.next += 1;
            let start = now(clock);
            let tracked = black_box(self.tracker.process(&sample.frame, arrivals).unwrap()).is_some();
            let elapsed = now(clock).saturating_sub(start);
            if tracked {
                return elapsed;
            }
        }
    }

    /// The total time of `iters` tracked frames.
    fn run(&mut self, iters: u64, clock: Clock) -> Duration {
        (0..iters).map(|_| self.next_tracked(clock)).sum()
    }
}

/// Prints the median time of `n` tracked frames with the wall clock and the
/// thread's CPU clock, and the frame rate against `target_fps`.
fn report_median(
    name: &str,
    frames: &[(RgbdSample, Arrivals)],
    make: &dyn Fn() -> Box<dyn OnlineTracker>,
    n: usize,
    target_fps: Option<f64>,
) {
    let mut line = format!("{name}: median per tracked frame at 640x480, one thread, {n} frames:");
    for (clock, label) in [(Clock::Wall, "wall"), (Clock::ThreadCpu, "CPU")] {
        let mut player = Player::new(frames, make);
        player.run(frames.len() as u64, clock); // warm-up
        let mut times: Vec<Duration> = (0..n).map(|_| player.next_tracked(clock)).collect();
        times.sort();
        let median = times[n / 2].as_secs_f64();
        let fps = 1.0 / median;
        let verdict = match target_fps {
            Some(target) if fps >= target => format!("meets the target of {target:.0} fps"),
            Some(target) => format!("BELOW the target of {target:.0} fps"),
            None => "for comparison, no target".to_string(),
        };
        line += &format!("\n  {label:>4}: {:.3} ms = {fps:.0} fps ({verdict})", median * 1e3);
    }
    println!("{line}");
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
    let mut player = Player::new(&frames, &make);
    c.bench_function("maskukf_frame_ycb_vga", |b| b.iter_custom(|iters| player.run(iters, Clock::Wall)));
    let mut player = Player::new(&frames, &make);
    c.bench_function("maskukf_frame_ycb_vga_cpu", |b| {
        b.iter_custom(|iters| player.run(iters, Clock::ThreadCpu))
    });
    report_median("MaskUKF (YCB-Video frames, cloud + sequential UKF)", &frames, &make, 500, Some(300.0));
}

fn roft(c: &mut Criterion) {
    let config = FastSequenceConfig::new(SimObjectKind::CrackerBox, 2.0, 3);
    let sequence = FastSequence::new(config).unwrap();
    let model = ObjectModel::from_mesh("cracker_box", sequence.mesh().clone());
    let intrinsics = sequence.intrinsics().clone();
    let mut network = SlowNetwork::new(SlowNetworkConfig::default());
    let mut frames = Vec::new();
    for k in 0..sequence.len() {
        let (frame, inside, truth) = sequence.frame(k);
        let mask = slidetrack_vision::cloud::mask(frame.depth.width, frame.depth.height, &inside).unwrap();
        let s = RgbdSample { frame, truth: Some(truth), truth_mask: Some(mask) };
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
    let mut player = Player::new(&frames, &make);
    c.bench_function("roft_frame_sim_vga_with_dis_flow", |b| {
        b.iter_custom(|iters| player.run(iters, Clock::Wall))
    });
    let mut player = Player::new(&frames, &make);
    c.bench_function("roft_frame_sim_vga_with_dis_flow_cpu", |b| {
        b.iter_custom(|iters| player.run(iters, Clock::ThreadCpu))
    });
    report_median("ROFT (simulated fast frames, DIS flow + KF + UKF)", &frames, &make, 300, Some(100.0));
    // The default flow covers the mask's box and a margin; the same with the
    // flow of the whole 640x480 frame, for comparison.
    let whole = TrackerSettings {
        flow: FlowConfig { margin_px: 10_000, ..FlowConfig::default() },
        ..TrackerSettings::default()
    };
    let make_whole = || build_tracker(TrackerKind::Roft, &model, &intrinsics, &whole).unwrap();
    report_median("ROFT, flow of the whole frame", &frames, &make_whole, 300, None);
}

fn one_core(c: &mut Criterion) {
    opencv::core::set_num_threads(1).unwrap();
    maskukf(c);
    roft(c);
}

criterion_group!(benches, one_core);
criterion_main!(benches);
