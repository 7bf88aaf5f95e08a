//! What `--ros2` costs `collect` (`bench --what collect-ros2`) when a
//! subscriber reads every published topic and never takes a sample (the
//! worst subscriber), against the same trials without `--ros2` (target: at
//! most 10 % slower, issue 27).
//!
//! The subscriber is a second DDS participant in this process, at normal
//! priority, pinned with the rest to one CPU: the cost measured includes
//! receiving every message, which a subscriber on another machine would not
//! charge to the recording's cores.

use std::sync::atomic::AtomicBool;

use anyhow::Result;
use serde_json::json;
use slidetrack_ros2::{Ros2Options, Ros2Publisher, StalledSubscriber};
use slidetrack_session::ros2::ros2_type;
use slidetrack_session::{ReadOptions, SessionInfo};
use slidetrack_sim::ObjectConfig;

use super::{BenchOptions, median};
use crate::rig::TrialSpec;
use crate::rig_config::RigConfig;
use crate::trial::run_sim_trial;

/// Least ratio of the real-time factor with `--ros2` to the one without.
const RATIO_TARGET: f64 = 0.9;

/// The DDS domain of the benchmark (out of the way of a default ROS 2 setup).
const BENCH_DOMAIN: u16 = 201;

/// Runs the trials, alternating without and with `--ros2`; `on_line` gets one line per pair.
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
        let publisher =
            Ros2Publisher::start(&Ros2Options { domain: BENCH_DOMAIN, ..Ros2Options::default() })?;
        let spec = |run: usize, ros2: bool, duration_s: f64| TrialSpec {
            rig: &rig,
            object: &object,
            seed: 1,
            trial: run as u32,
            duration_s,
            camera,
            realtime: false,
            overwrite: true,
            path: dir.join(format!("bench-ros2-{camera}-{ros2}-{run}.mcap")),
            live: ros2.then(|| publisher.tap()),
        };
        // A first short trial creates the writers; the subscriber reads every topic.
        let warm = spec(0, true, 1.0);
        run_sim_trial(&warm, &stop, &mut |_| {})?;
        let channels = SessionInfo::read(&warm.path, ReadOptions::default())?.channels;
        let mut topics: Vec<(&str, &str)> = channels
            .iter()
            .filter_map(|c| ros2_type(&c.schema_name, &c.topic).map(|(t, r)| (r, t)))
            .collect();
        topics.sort_unstable();
        topics.dedup();
        let subscriber = StalledSubscriber::subscribe(BENCH_DOMAIN, &topics)?;
        // Discovery: the writers and the readers match within a second on one host.
        std::thread::sleep(std::time::Duration::from_secs(2));
        let (mut without_s, mut with_s, mut session_s) = (Vec::new(), Vec::new(), 0.0);
        for run in 0..args.runs.max(1) {
            for ros2 in [false, true] {
                let spec = spec(run, ros2, args.duration_s);
                let report = run_sim_trial(&spec, &stop, &mut |_| {})?;
                if ros2 { &mut with_s } else { &mut without_s }.push(report.wall_s);
                session_s = report.outcome.end.as_secs_f64();
                let _ = std::fs::remove_file(&spec.path);
            }
        }
        let stats = publisher.finish();
        drop(subscriber);
        let (rtf_without, rtf_with) = (session_s / median(&without_s), session_s / median(&with_s));
        let ratio = rtf_with / rtf_without;
        out.push(json!({
            "what": label,
            "session_s": session_s,
            "without_ros2_median_wall_s": median(&without_s),
            "with_ros2_median_wall_s": median(&with_s),
            "without_ros2_times_real_time": rtf_without,
            "with_ros2_times_real_time": rtf_with,
            "ratio": ratio,
            "target_ratio": RATIO_TARGET,
            "pass": ratio >= RATIO_TARGET,
            "topics": topics.len(),
            "messages_published": stats.node.published,
            "messages_dropped": stats.tap.dropped,
        }));
        on_line(format!(
            "  {label:<32} without --ros2 {rtf_without:>7.1}x real time, with --ros2 and a stalled subscriber \
             {rtf_with:>7.1}x: ratio {ratio:.3} (target >= {RATIO_TARGET}): {}; {} published, {} dropped",
            if ratio >= RATIO_TARGET { "PASS" } else { "FAIL" },
            stats.node.published,
            stats.tap.dropped
        ));
    }
    Ok(out)
}

/// The header line of the text report.
pub fn header(args: &BenchOptions, cpu: usize) -> String {
    format!(
        "collect-ros2: box, {} s of sliding cycles, pinned to CPU {cpu}, median of {} runs each; a subscriber \
         in this process reads every topic (QoS as offered) and never takes a sample",
        args.duration_s,
        args.runs.max(1)
    )
}
