//! `slidetrack record`: the configured devices recorded into a session, with
//! no protocol and the hand not driven.

use anyhow::{Result, bail};
use indicatif::{ProgressBar, ProgressStyle};
use slidetrack_core::TimeNs;
use slidetrack_experiment::record::{RecordEnd, record_devices};
use slidetrack_experiment::rig::{HandUse, RigKind, TrialSpec, build_rig_with};
use slidetrack_experiment::trial::prepare_out_dir;
use slidetrack_experiment::trial_inputs::TrialInputs;

use crate::cli::{RecordArgs, RigArg};

pub fn run(args: &RecordArgs, quiet: bool) -> Result<()> {
    if let Some(d) = args.duration
        && !(d.is_finite() && d > 0.0)
    {
        bail!("--duration must be a positive number of seconds, got {d}");
    }
    let kind = match args.rig {
        RigArg::Sim => RigKind::Sim,
        RigArg::Hw => RigKind::Hw,
        RigArg::Replay => bail!("record records live devices; a recorded session is already a recording"),
    };
    let TrialInputs { object, rig } = TrialInputs::load(&args.object, args.config.as_deref())?;
    if let Some(dir) = args.out.parent().filter(|d| !d.as_os_str().is_empty()) {
        prepare_out_dir(dir)?;
    }
    // Before any device moves: an address or domain that cannot serve stops here.
    let outlets = super::live::start(&args.live)?;
    let spec = TrialSpec {
        rig: &rig,
        object: &object,
        seed: args.seed,
        trial: 0,
        duration_s: args.duration.unwrap_or(0.0),
        camera: !args.no_camera,
        // `--rig sim` runs as fast as it can; real and emulated devices keep the wall clock.
        realtime: false,
        overwrite: args.overwrite,
        path: args.out.clone(),
        live: outlets.tap(),
    };
    let stop = super::stop_flag("closing the session (the hand is left as it is)");
    let bar = progress_bar(args, quiet);
    let mut progress = |t: TimeNs| {
        let ms = (t.as_secs_f64() * 1e3) as u64;
        match args.duration {
            Some(_) => bar.set_position(ms.min(bar.length().unwrap_or(ms))),
            None => bar.set_message(format!("{:.1} s", t.as_secs_f64())),
        }
    };
    let setup = build_rig_with(kind, &spec, HandUse::Watch)?;
    let report = record_devices(setup, &spec, args.duration, &stop, &mut progress);
    bar.finish_and_clear();
    super::live::finish(outlets);
    let report = report?;
    println!("{}", report.summary_line());
    if let Some(counters) = report.stats.decoder {
        println!("  tactile decoder: {counters}");
    }
    match &report.end {
        RecordEnd::Duration | RecordEnd::Interrupted => Ok(()),
        RecordEnd::Device(e) => bail!(
            "recording stopped: {e}; {} keeps the {} scans recorded so far",
            report.path.display(),
            report.stats.scans
        ),
        RecordEnd::Recording(e) => bail!("recording stopped: {e}; {} is finished", report.path.display()),
    }
}

/// A bar over `--duration`, or a spinner with the session time without one.
fn progress_bar(args: &RecordArgs, quiet: bool) -> ProgressBar {
    let bar = match (quiet, args.duration) {
        (true, _) => ProgressBar::hidden(),
        (false, Some(d)) => ProgressBar::new((d * 1e3) as u64),
        (false, None) => ProgressBar::new_spinner(),
    };
    let template = if args.duration.is_some() {
        "recording [{bar:30}] {percent:>3}%, {elapsed} (Ctrl-C stops)"
    } else {
        "recording {spinner} {msg} (Ctrl-C stops)"
    };
    bar.set_style(
        ProgressStyle::with_template(template)
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
    );
    bar
}
