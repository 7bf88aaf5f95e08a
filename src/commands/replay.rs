//! `slidetrack replay`: run the grasp-state detector and, with `--model`, a
//! dEKF model over a recorded session (through the replay rig, as `track`
//! runs them live; imported sessions over their recorded scans) and write a
//! copy of the session with their estimates.

use std::path::Path;

use anyhow::{Context, Result, bail};
use slidetrack_estimators::dekf::{DekfModel, DekfOutput};
use slidetrack_estimators::slip::GraspDetectorConfig;
use slidetrack_experiment::channels::recorded_tactile;
use slidetrack_experiment::dataset::load;
use slidetrack_experiment::dekf_eval::has_protocol;
use slidetrack_experiment::dekf_run::{estimate_channel, estimate_metadata, load_model, run};
use slidetrack_experiment::grasp_eval::run_offline;
use slidetrack_experiment::grasp_state::{channel_metadata, for_source};
use slidetrack_experiment::plot::dekf::plot_replay;
use slidetrack_experiment::replay::{ReplayEstimates, replay_estimates};
use slidetrack_session::{
    NewChannel, ReadOptions, SessionInfo, SlipEstimate, TactileDerivative, rewrite_session,
};

use crate::cli::ReplayArgs;

pub fn run_cmd(args: &ReplayArgs) -> Result<()> {
    let model = args.model.as_deref().map(load_model).transpose()?;
    if args.out.exists() && !args.overwrite {
        bail!("{} already exists; pass --overwrite to replace it", args.out.display());
    }
    if std::fs::canonicalize(&args.file).ok() == std::fs::canonicalize(&args.out).ok() {
        bail!("--out must differ from the input file");
    }
    let cfg = GraspDetectorConfig::default();
    let estimates = estimates(&args.file, model.as_ref(), cfg)?;
    // The settings the stage ran with (the simulated rig's contact level on
    // a simulated session).
    let info = SessionInfo::read(&args.file, ReadOptions::default())?;
    let ran = match recorded_tactile(&args.file, &info)? {
        Some(tactile) => for_source(cfg, &tactile),
        None => cfg,
    };
    let mut channels = vec![slip_channel(channel_metadata(&ran)?, &estimates.slip)?];
    if let (Some(model), Some(path)) = (&model, &args.model) {
        channels.extend(dekf_channels(model, path, &estimates.dekf)?);
    }
    let tmp = args.out.with_extension("mcap.partial");
    std::fs::copy(&args.file, &tmp)
        .with_context(|| format!("cannot copy {} to {}", args.file.display(), tmp.display()))?;
    let result = rewrite_session(&tmp, ReadOptions::default(), &|_| false, channels);
    if let Err(e) = result {
        let _ = std::fs::remove_file(&tmp);
        return Err(e.into());
    }
    std::fs::rename(&tmp, &args.out).with_context(|| format!("cannot write {}", args.out.display()))?;
    let dekf = if model.is_some() { format!(", {} dEKF steps", estimates.dekf.len()) } else { String::new() };
    println!("{}: {} grasp-detector scans{dekf}", args.out.display(), estimates.slip.len());
    if let Some(plot) = &args.plot {
        plot_replay(&args.file, &estimates.dekf, plot)?;
        println!("{}", plot.display());
    }
    Ok(())
}

/// The estimates of the session at `path`. Sessions recorded without the protocol (imports) have nothing
/// to replay it on: the estimators run over their recorded zeroed scans.
fn estimates(path: &Path, model: Option<&DekfModel>, cfg: GraspDetectorConfig) -> Result<ReplayEstimates> {
    if has_protocol(path)? {
        return replay_estimates(path, model, Some(cfg));
    }
    let dekf = match model {
        Some(model) => run(model, &load(path, None)?)?,
        None => Vec::new(),
    };
    let offline = run_offline(path, cfg)?;
    let slip = offline.times.iter().copied().zip(offline.estimates).collect();
    Ok(ReplayEstimates { dekf, slip })
}

fn slip_channel(
    metadata: std::collections::BTreeMap<String, String>,
    estimates: &[(slidetrack_core::TimeNs, SlipEstimate)],
) -> Result<NewChannel> {
    let mut channel = NewChannel::of::<SlipEstimate>(metadata);
    for (t, e) in estimates {
        channel.push_json(*t, e)?;
    }
    Ok(channel)
}

fn dekf_channels(
    model: &DekfModel,
    path: &Path,
    outputs: &[(slidetrack_core::TimeNs, DekfOutput)],
) -> Result<[NewChannel; 2]> {
    let model_name = path.file_name().map_or(String::new(), |n| n.to_string_lossy().into_owned());
    let [derivative_meta, estimate_meta] = estimate_metadata(model, &model_name)?;
    let mut derivative = NewChannel::of::<TactileDerivative>(derivative_meta);
    for (t, o) in outputs {
        derivative.push_json(*t, &TactileDerivative { values: o.measurement.clone() })?;
    }
    Ok([derivative, estimate_channel(model, estimate_meta, outputs)?])
}
