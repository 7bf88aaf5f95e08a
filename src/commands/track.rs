//! `slidetrack track`: the controlled-sliding experiment with the dEKF live
//! on every tactile scan and a causal Kalman filter on the marker, recorded
//! to one session and shown in the terminal; on the replay rig, the same on a
//! recorded session.

use anyhow::{Result, bail};
use indicatif::{ProgressBar, ProgressStyle};
use slidetrack_experiment::tracked_trial::{TrackOptions, TrackRig, TrackRun, TrackedTrial, TrialHooks};
use slidetrack_experiment::tracking::CameraVisionSummary;
use slidetrack_experiment::vision::TrackerKind;
use slidetrack_experiment::vision::camera::StreamCounts;

use crate::cli::{RigArg, TrackArgs};

pub fn run(args: &TrackArgs, quiet: bool) -> Result<()> {
    let run = TrackRun::prepare(options(args))?;
    let live = super::live::start(&args.run.live)?;
    let display = if quiet { ProgressBar::hidden() } else { ProgressBar::new_spinner() };
    display.set_style(
        ProgressStyle::with_template("{msg}").unwrap_or_else(|_| ProgressStyle::default_spinner()),
    );
    display.enable_steady_tick(std::time::Duration::from_millis(100));
    let line = display.clone();
    let hooks = TrialHooks {
        stop: &|| super::stop_flag(super::RELEASING),
        show: Box::new(move |text: &str| line.set_message(text.to_string())),
    };
    let tracked = run.run(live.tap(), hooks);
    display.finish_and_clear();
    super::live::finish(live);
    let tracked = tracked?;
    print_summary(args, &tracked)
}

/// The options of `args`.
fn options(args: &TrackArgs) -> TrackOptions<'_> {
    TrackOptions {
        rig: match args.run.rig {
            RigArg::Sim => TrackRig::Sim,
            RigArg::Hw => TrackRig::Hw,
            RigArg::Replay => TrackRig::Replay,
        },
        model: &args.model,
        object: &args.run.object,
        config: args.run.config.as_deref(),
        session: args.run.session.as_deref(),
        seed: args.run.seed,
        trial: args.trial,
        duration_s: args.run.duration,
        camera: !args.run.no_camera,
        realtime: args.run.realtime,
        overwrite: args.run.overwrite,
        out: args.out.clone(),
        vision: args.vision.map(|kind| args.camera.options(kind)),
        record_rgbd: args.record_rgbd,
    }
}

/// The trial's summary and the trackers' errors against the simulator's truth.
fn print_summary(args: &TrackArgs, tracked: &TrackedTrial) -> Result<()> {
    let TrackedTrial { report, status, streams } = tracked;
    println!("{}", report.summary_line());
    println!("  dEKF: {} steps; /tactile/derivative, /estimate/dekf recorded", status.dekf_steps);
    if let Some(grasp) = status.grasp {
        println!("  grasp detector: /estimate/slip recorded, last state {}", grasp.as_str());
    }
    if let Some([p, v, base]) = status.dekf_errors.rmse() {
        println!(
            "  dEKF against the simulator's truth until the release: position RMSE {p:.3} cm (zero-motion baseline {base:.3} cm), velocity RMSE {v:.3} cm/s"
        );
    }
    if let Some([p, v, _]) = status.marker_errors.rmse() {
        println!(
            "  marker KF (/estimate/aruco) against the simulator's truth: position RMSE {p:.3} cm, velocity RMSE {v:.3} cm/s"
        );
    }
    if let (Some(kind), Some([p, v, _])) = (args.vision, status.vision_errors.rmse()) {
        println!(
            "  vision ({}) along the sliding axis against the simulator's truth: position RMSE {p:.3} cm, velocity RMSE {v:.3} cm/s",
            TrackerKind::from(kind).name()
        );
    }
    if let (Some(summary), Some(kind)) = (&status.camera_vision, args.vision) {
        print_camera_vision(TrackerKind::from(kind), summary, streams.as_ref());
    }
    if let Some(reason) = &report.outcome.abort {
        bail!("the trial was aborted: {reason}; {} keeps what was recorded", report.path.display());
    }
    Ok(())
}

/// The summary lines of the vision tracker on the rig's camera; why it
/// stopped, if it stopped before the trial, on stderr.
pub(super) fn print_camera_vision(
    kind: TrackerKind,
    s: &CameraVisionSummary,
    streams: Option<&StreamCounts>,
) {
    println!(
        "  vision ({}) on the [rgbd] camera: {} of {} frames tracked, {:.0} fps (tracker only); \
         /rgbd/*, /estimate/*/{} recorded",
        kind.name(),
        s.tracked,
        s.frames,
        s.tracker_fps,
        kind.name()
    );
    for line in streams.map(StreamCounts::lines).unwrap_or_default().iter().chain(&s.measurements) {
        println!("    {line}");
    }
    if let Some(e) = &s.error {
        eprintln!("warning: the vision tracker stopped before the trial ended: {e}");
    }
}
