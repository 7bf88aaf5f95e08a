//! What `--live` costs `collect` (`bench --what collect-live`)
//! when a viewer subscribes to every channel and never reads (the worst
//! viewer), against the same trials without `--live` (target: at most 10 %
//! slower).

use std::sync::atomic::AtomicBool;
use std::time::Duration;

use anyhow::Result;
use serde_json::json;
use slidetrack_live::{LiveOptions, LiveServer, StalledViewer};
use slidetrack_session::{ReadOptions, SessionInfo};
use slidetrack_sim::ObjectConfig;

use super::{BenchOptions, median};
use crate::rig::TrialSpec;
use crate::rig_config::RigConfig;
use crate::trial::run_sim_trial;

/// Least ratio of the real-time factor with `--live` to the one without.
const RATIO_TARGET: f64 = 0.9;

/// One pair of measurements: the same trials with and without `--live`.
struct Pair {
    label: &'static str,
    session_s: f64,
    without_s: Vec<f64>,
    with_s: Vec<f64>,
    /// Messages the viewer side dropped or thinned, for the record.
    published: u64,
}

impl Pair {
    fn rtf(&self, wall: &[f64]) -> f64 {
        self.session_s / median(wall)
    }

    fn ratio(&self) -> f64 {
        self.rtf(&self.with_s) / self.rtf(&self.without_s)
    }

    fn to_json(&self) -> serde_json::Value {
        json!({
            "what": self.label,
            "session_s": self.session_s,
            "without_live_median_wall_s": median(&self.without_s),
            "with_live_median_wall_s": median(&self.with_s),
            "without_live_times_real_time": self.rtf(&self.without_s),
            "with_live_times_real_time": self.rtf(&self.with_s),
            "ratio": self.ratio(),
            "target_ratio": RATIO_TARGET,
            "pass": self.ratio() >= RATIO_TARGET,
            "messages_published": self.published,
        })
    }
}

/// Runs the trials, alternating without and with `--live` so that drifts of
/// the machine hit both alike; `on_line` gets one line per pair.
pub fn measure(
    args: &BenchOptions,
    dir: &std::path::Path,
    on_line: &mut dyn FnMut(String),
) -> Result<Vec<serde_json::Value>> {
    crate::bench::use_one_thread();
    let rig = RigConfig::default();
    let object = ObjectConfig::load("box")?;
    let stop = AtomicBool::new(false);
    let mut out = Vec::new();
    for (label, camera) in [("with camera + marker detection", true), ("without camera", false)] {
        // Every image to the viewer: the worst case.
        let options = LiveOptions { image_max_hz: 0.0, ..LiveOptions::default() };
        let server = LiveServer::start("127.0.0.1:0", &options)?;
        let spec = |run: usize, live: bool, duration_s: f64| TrialSpec {
            rig: &rig,
            object: &object,
            seed: 1,
            trial: run as u32,
            duration_s,
            camera,
            realtime: false,
            overwrite: true,
            path: dir.join(format!("bench-live-{camera}-{live}-{run}.mcap")),
            live: live.then(|| server.tap()),
        };
        // A first short trial advertises the channels; the viewer subscribes to them all.
        let warm = spec(0, true, 1.0);
        run_sim_trial(&warm, &stop, &mut |_| {})?;
        let channels = SessionInfo::read(&warm.path, ReadOptions::default())?.channels.len();
        let viewer = StalledViewer::subscribe_all(server.local_addr(), channels, Duration::from_secs(10))?;
        let mut pair =
            Pair { label, session_s: 0.0, without_s: Vec::new(), with_s: Vec::new(), published: 0 };
        for run in 0..args.runs.max(1) {
            for live in [false, true] {
                let spec = spec(run, live, args.duration_s);
                let report = run_sim_trial(&spec, &stop, &mut |_| {})?;
                if live { &mut pair.with_s } else { &mut pair.without_s }.push(report.wall_s);
                pair.session_s = report.outcome.end.as_secs_f64();
                let _ = std::fs::remove_file(&spec.path);
            }
        }
        let subscribed = viewer.subscribed().len();
        pair.published = server.shutdown().published;
        drop(viewer);
        if subscribed < channels {
            anyhow::bail!("the viewer subscribed to {subscribed} of {channels} channels");
        }
        out.push(pair.to_json());
        on_line(format!(
            "  {label:<32} without --live {:>7.1}x real time, with --live and a stalled viewer {:>7.1}x: ratio {:.3} (target >= {RATIO_TARGET}): {}",
            pair.rtf(&pair.without_s),
            pair.rtf(&pair.with_s),
            pair.ratio(),
            if pair.ratio() >= RATIO_TARGET { "PASS" } else { "FAIL" }
        ));
    }
    Ok(out)
}

/// The header line of the text report.
pub fn header(args: &BenchOptions, cpu: usize) -> String {
    format!(
        "collect-live: box, {} s of sliding cycles, pinned to CPU {cpu}, median of {} runs each; the viewer subscribes to every channel (every image) and never reads",
        args.duration_s,
        args.runs.max(1)
    )
}
