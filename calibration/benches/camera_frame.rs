//! The simulated camera's per-frame path on one core: render, JPEG encode,
//! marker detection (whole frame and tracked region of interest), pose.
//!
//! Run with `cargo bench -p slidetrack-calibration --bench camera_frame`.
//! Before the criterion groups it prints the median of every stage over a
//! 5 cm slide and says whether the whole path fits the 3 ms budget (a 60 s
//! trial at 30 Hz in under 6 s, 10x faster than real time, with room for
//! physics and recording).

use std::hint::black_box;
use std::time::{Duration, Instant};

use criterion::{BatchSize, Criterion};
use nalgebra::{Isometry3, Translation3, UnitQuaternion};
use slidetrack_calibration::{Dictionary, MarkerDetector, MarkerTracker, marker_pattern, marker_pose};
use slidetrack_core::{Image, PixelFormat, encode_jpeg};
use slidetrack_sim::camera::{ObjectAppearance, SimCameraConfig, SimCameraRenderer};

/// Budget for the whole per-frame path (ms).
const BUDGET_MS: f64 = 3.0;
/// Frames of the slide.
const FRAMES: u64 = 300;

fn renderer(format: PixelFormat) -> SimCameraRenderer {
    let config = SimCameraConfig { pixel_format: format, ..SimCameraConfig::default() };
    let marker = marker_pattern("DICT_6X6_250", 7).expect("DICT_6X6_250 id 7 exists");
    SimCameraRenderer::new(config, ObjectAppearance::default(), marker, 7).expect("default config is valid")
}

/// The object 0.10 m in front of the palm, slid down by 5 cm over the frames.
fn hand_from_object(frame: u64) -> Isometry3<f64> {
    let drop_m = 0.05 * (frame % FRAMES) as f64 / FRAMES as f64;
    Isometry3::from_parts(Translation3::new(0.10, 0.0, -drop_m), UnitQuaternion::identity())
}

fn tracker() -> MarkerTracker {
    MarkerTracker::new(Dictionary::from_name("DICT_6X6_250").expect("known"), 7).expect("tracker")
}

fn median_ms(mut samples: Vec<Duration>) -> f64 {
    samples.sort();
    samples[samples.len() / 2].as_secs_f64() * 1e3
}

/// Times every stage frame by frame and prints the medians.
fn summary(format: PixelFormat) {
    let mut r = renderer(format);
    let intrinsics = r.intrinsics().clone();
    let mut full =
        MarkerDetector::new(Dictionary::from_name("DICT_6X6_250").expect("known")).expect("detector");
    let mut tracked = tracker();
    let mut stages: [Vec<Duration>; 6] = Default::default();
    let mut found = 0;
    for k in 0..FRAMES {
        let pose = hand_from_object(k);
        let t0 = Instant::now();
        let image = r.render_image(&pose, k);
        let t1 = Instant::now();
        let jpeg = encode_jpeg(&image, r.config().jpeg_quality).expect("encodes");
        let t2 = Instant::now();
        let detection = tracked.detect(&image).expect("detects");
        let t3 = Instant::now();
        let marker = detection.map(|d| marker_pose(&d, &intrinsics, 0.03).expect("pose"));
        let t4 = Instant::now();
        black_box((jpeg, &marker));
        found += usize::from(marker.is_some());
        let t5 = Instant::now();
        black_box(full.detect(&image).expect("detects"));
        let t6 = Instant::now();
        for (stage, d) in stages.iter_mut().zip([t1 - t0, t2 - t1, t3 - t2, t4 - t3, t4 - t0, t6 - t5]) {
            stage.push(d);
        }
    }
    let [render, encode, detect, pose, whole, detect_full] = stages.map(median_ms);
    let (roi_hits, full_searches) = tracked.counts();
    println!(
        "camera_frame {format:?} 640x480, 1 thread, medians over {FRAMES} frames: render {render:.3} ms, \
         JPEG {encode:.3} ms, detect (tracked ROI) {detect:.3} ms, pose {pose:.3} ms, whole path {whole:.3} ms \
         ({verdict} the {BUDGET_MS} ms budget); whole-frame detection {detect_full:.3} ms; \
         marker found in {found}/{FRAMES} frames ({roi_hits} in the ROI, {full_searches} full searches)",
        verdict = if whole <= BUDGET_MS { "meets" } else { "EXCEEDS" },
    );
}

fn benches(c: &mut Criterion) {
    for (format, name) in [(PixelFormat::Gray8, "gray"), (PixelFormat::Rgb8, "rgb")] {
        let mut r = renderer(format);
        let intrinsics = r.intrinsics().clone();
        let quality = r.config().jpeg_quality;
        let frames: Vec<Image> = (0..30).map(|k| r.render_image(&hand_from_object(k * 10), k)).collect();
        let mut group = c.benchmark_group(format!("camera_frame/{name}"));
        let mut k = 0u64;
        group.bench_function("render", |b| {
            b.iter(|| {
                k += 1;
                r.render_image(&hand_from_object(k), k)
            })
        });
        group
            .bench_function("jpeg_encode", |b| b.iter(|| encode_jpeg(&frames[0], quality).expect("encodes")));
        let mut full =
            MarkerDetector::new(Dictionary::from_name("DICT_6X6_250").expect("known")).expect("detector");
        group.bench_function("detect_whole_frame", |b| b.iter(|| full.detect(&frames[0]).expect("detects")));
        group.bench_function("detect_tracked_roi", |b| {
            b.iter_batched_ref(
                || {
                    let mut t = tracker();
                    t.detect(&frames[0]).expect("detects");
                    t
                },
                |t| t.detect(&frames[1]).expect("detects"),
                BatchSize::SmallInput,
            )
        });
        let detection = full.detect(&frames[0]).expect("detects").remove(0);
        group
            .bench_function("pose", |b| b.iter(|| marker_pose(&detection, &intrinsics, 0.03).expect("pose")));
        let mut t = tracker();
        let mut k = 0u64;
        group.bench_function("whole_path", |b| {
            b.iter(|| {
                k += 1;
                let frame = r.render(&hand_from_object(k), slidetrack_core::TimeNs(k), k);
                let image = frame.pixels.as_ref().expect("rendered pixels");
                let d = t.detect(image).expect("detects");
                (frame, d.map(|d| marker_pose(&d, &intrinsics, 0.03)))
            })
        });
        group.finish();
    }
}

fn main() {
    opencv::core::set_num_threads(1).expect("OpenCV accepts one thread");
    summary(PixelFormat::Gray8);
    summary(PixelFormat::Rgb8);
    let mut c = Criterion::default().configure_from_args();
    benches(&mut c);
    c.final_summary();
}
