//! The in-hand rig's whole vision step (`InHandVision::on_frame`: rendering
//! the RGB-D frame, the imitated network and the tracker) on one core,
//! against the camera's 30 fps: the budget of `slidetrack track --vision`
//! in real time. Prints the median CPU time of the tracking thread per frame.
#![expect(clippy::unwrap_used, reason = "benchmark code: a failed unwrap is a failed run")]

use std::hint::black_box;
use std::time::Duration;

use slidetrack_core::TimeNs;
use slidetrack_experiment::vision_inhand::{InHandVision, InHandVisionConfig};
use slidetrack_sim::ObjectConfig;
use slidetrack_sim::camera::SimCameraConfig;
use slidetrack_vision::TrackerKind;

/// CPU time of this thread.
fn thread_cpu() -> Duration {
    let t = nix::time::clock_gettime(nix::time::ClockId::CLOCK_THREAD_CPUTIME_ID).unwrap();
    Duration::new(t.tv_sec() as u64, t.tv_nsec() as u32)
}

/// The in-hand rig's vision step (`InHandVision::on_frame`: rendering the
/// RGB-D frame, the imitated network and the tracker) against the camera's
/// 30 Hz, the budget of `slidetrack track --vision` in real time.
fn main() {
    opencv::core::set_num_threads(1).unwrap();

    let object = ObjectConfig::load("box").unwrap();
    for kind in [TrackerKind::MaskUkf, TrackerKind::Roft] {
        let mut vision = InHandVision::new(
            &InHandVisionConfig::new(kind, 1),
            &SimCameraConfig::default(),
            &object.geometry,
            [0.10, 0.0, 0.0],
            [0.0, 0.0, -1.0],
        )
        .unwrap();
        let mut times: Vec<Duration> = (0..150u64)
            .map(|k| {
                let t = k as f64 / 30.0;
                let travel = 0.02 * (1.0 - (t * 2.0).cos());
                let start = thread_cpu();
                black_box(
                    vision.on_frame(TimeNs((t * 1e9) as u64), k, travel, 0.04 * (t * 2.0).sin()).unwrap(),
                );
                thread_cpu().saturating_sub(start)
            })
            .collect();
        times.sort();
        let median = times[times.len() / 2].as_secs_f64();
        println!(
            "in-hand {} (render + network + tracker): median {:.3} ms CPU = {:.0} fps (camera: 30 fps)",
            kind.name(),
            median * 1e3,
            1.0 / median
        );
    }
}
