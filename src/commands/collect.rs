//! `slidetrack collect`: controlled-sliding trials, one session file each.

use std::sync::atomic::Ordering;

use anyhow::{Result, bail};
use indicatif::{ProgressBar, ProgressStyle};
use slidetrack_core::TimeNs;
use slidetrack_experiment::collect_vision::{CollectedTrial, collect_trial};
use slidetrack_experiment::rig::{RigKind, TrialSpec};
use slidetrack_experiment::trial::{TrialReport, prepare_out_dir, session_file_name};
use slidetrack_experiment::trial_inputs::TrialInputs;
use slidetrack_experiment::vision::TrackerKind;

use crate::cli::{CollectArgs, RigArg};

/// Expected length of a trial beyond its cycles: zeroing, closing, ramp,
/// settle and release (s), for the progress bar.
const SETUP_S: f64 = 5.0;

pub fn run(args: &CollectArgs, quiet: bool) -> Result<()> {
    let reports = collect(args, quiet)?;
    if reports.is_empty() {
        bail!("no trial ran");
    }
    Ok(())
}

/// Runs the trials of `args`, printing one line per trial; returns their reports.
pub fn collect(args: &CollectArgs, quiet: bool) -> Result<Vec<TrialReport>> {
    let kind = rig_kind(args)?;
    let TrialInputs { object, rig } = TrialInputs::load(&args.run.object, args.run.config.as_deref())?;
    prepare_out_dir(&args.out)?;
    // Before any device moves: an address that cannot serve stops here.
    let live = super::live::start(&args.run.live)?;
    let stop = super::stop_flag(super::RELEASING);
    let vision = args.vision.map(|kind| args.camera.options(kind));
    let config = args.run.config.as_deref().unwrap_or(std::path::Path::new("rig.toml"));

    let per_trial_ms = ((args.run.duration + SETUP_S) * 1e3) as u64;
    let bar = progress_bar(quiet, per_trial_ms * u64::from(args.trials));
    let mut reports = Vec::new();
    for (k, trial) in (args.first_trial..args.first_trial + args.trials).enumerate() {
        let path = args.out.join(session_file_name(&object.name, args.run.seed, trial));
        bar.set_message(format!("{} trial {}/{}", object.name, k + 1, args.trials));
        let offset_ms = per_trial_ms * k as u64;
        let spec = TrialSpec {
            rig: &rig,
            object: &object,
            seed: args.run.seed,
            trial,
            duration_s: args.run.duration,
            camera: !args.run.no_camera,
            realtime: args.run.realtime,
            overwrite: args.run.overwrite,
            path,
            live: live.tap(),
        };
        let mut progress = |t: TimeNs| {
            bar.set_position(offset_ms + ((t.as_secs_f64() * 1e3) as u64).min(per_trial_ms));
        };
        let collected =
            collect_trial(kind, &spec, vision.as_ref().map(|v| (v, config)), &stop, &mut progress)?;
        after_trial(&collected, args, trial, &bar)?;
        reports.push(collected.report);
        if stop.load(Ordering::SeqCst) {
            bar.finish_and_clear();
            bail!("interrupted after {} trial(s); the sessions written so far are complete", reports.len());
        }
    }
    bar.finish_and_clear();
    super::live::finish(live);
    Ok(reports)
}

/// The rig of `args`, its options checked.
fn rig_kind(args: &CollectArgs) -> Result<RigKind> {
    if !(args.run.duration.is_finite() && args.run.duration > 0.0) {
        bail!("--duration must be a positive number of seconds, got {}", args.run.duration);
    }
    if args.trials == 0 {
        bail!("--trials must be at least 1");
    }
    if args.vision.is_some() && args.run.config.is_none() {
        bail!("--vision tracks the RGB-D camera of the rig TOML: give --config RIG.toml");
    }
    Ok(match args.run.rig {
        RigArg::Sim => RigKind::Sim,
        RigArg::Hw => RigKind::Hw,
        RigArg::Replay => bail!(
            "collect records new trials; to run the trackers on a recorded session use \
             `slidetrack track --rig replay --session FILE` (or `slidetrack replay`)"
        ),
    })
}

/// The bar of `total_ms` of session time over all trials.
fn progress_bar(quiet: bool, total_ms: u64) -> ProgressBar {
    let bar = if quiet { ProgressBar::hidden() } else { ProgressBar::new(total_ms) };
    bar.set_style(
        ProgressStyle::with_template("{msg} [{bar:30}] {percent:>3}% sim time, {elapsed} wall, eta {eta}")
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
    );
    bar
}

/// The lines of one trial; an error when a device stopped it.
fn after_trial(collected: &CollectedTrial, args: &CollectArgs, trial: u32, bar: &ProgressBar) -> Result<()> {
    let report = &collected.report;
    bar.suspend(|| println!("{}", report.summary_line()));
    if let (Some(summary), Some(kind)) = (&collected.vision, args.vision) {
        bar.suspend(|| super::track::print_camera_vision(TrackerKind::from(kind), summary, None));
    }
    if let Some(counters) = report.stats.decoder {
        bar.suspend(|| println!("  tactile decoder: {counters}"));
    }
    if report.images_dropped > 0 {
        tracing::warn!(
            "{}: {} camera images dropped under back-pressure",
            report.path.display(),
            report.images_dropped
        );
    }
    if let Some(e) = report.device_error() {
        bar.finish_and_clear();
        let hand = match &report.outcome.release_error {
            None => "the hand was released".to_string(),
            Some(r) => format!("releasing the hand failed too ({r})"),
        };
        bail!(
            "trial {trial} stopped: {e}; {hand}; {} keeps the {} scans recorded so far",
            report.path.display(),
            report.stats.scans
        );
    }
    Ok(())
}
