//! A recorded session's estimates written into a copy of it (`replay`): the
//! grasp-state detector and, with a model, the dEKF run over it (through the
//! replay rig, as `track` runs them live; imported sessions over their
//! recorded scans).

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use slidetrack_estimators::dekf::{DekfModel, DekfOutput};
use slidetrack_estimators::slip::GraspDetectorConfig;
use slidetrack_session::{
    NewChannel, ReadOptions, SessionInfo, SlipEstimate, TactileDerivative, rewrite_session,
};

use crate::channels::recorded_tactile;
use crate::dataset::load;
use crate::dekf_eval::has_protocol;
use crate::dekf_run::{estimate_channel, estimate_metadata, load_model, run};
use crate::grasp_eval::run_offline;
use crate::grasp_state::{channel_metadata, for_source};
use crate::replay::{ReplayEstimates, replay_estimates};

/// What to replay and where to write it.
#[derive(Clone, Debug)]
pub struct ReplayFileOptions {
    /// The recorded session.
    pub file: PathBuf,
    /// The dEKF model to run too.
    pub model: Option<PathBuf>,
    /// The copy with the estimates.
    pub out: PathBuf,
    /// Replace `out` if it exists.
    pub overwrite: bool,
}

/// The estimates of a replay, written into the copy.
pub struct ReplayedFile {
    /// The estimates.
    pub estimates: ReplayEstimates,
    /// True when a dEKF model ran.
    pub with_model: bool,
}

/// Runs the estimators over `options.file` and writes its copy with their
/// channels (`/estimate/slip`, and `/tactile/derivative`, `/estimate/dekf`
/// with a model) to `options.out`, atomically.
pub fn replay_into_copy(options: &ReplayFileOptions) -> Result<ReplayedFile> {
    let model = options.model.as_deref().map(load_model).transpose()?;
    if options.out.exists() && !options.overwrite {
        bail!("{} already exists; pass --overwrite to replace it", options.out.display());
    }
    if std::fs::canonicalize(&options.file).ok() == std::fs::canonicalize(&options.out).ok() {
        bail!("--out must differ from the input file");
    }
    let cfg = GraspDetectorConfig::default();
    let estimates = estimates(&options.file, model.as_ref(), cfg)?;
    // The settings the stage ran with (the simulated rig's contact level on
    // a simulated session).
    let info = SessionInfo::read(&options.file, ReadOptions::default())?;
    let ran = match recorded_tactile(&options.file, &info)? {
        Some(tactile) => for_source(cfg, &tactile),
        None => cfg,
    };
    let mut channels = vec![slip_channel(channel_metadata(&ran)?, &estimates.slip)?];
    if let (Some(model), Some(path)) = (&model, &options.model) {
        channels.extend(dekf_channels(model, path, &estimates.dekf)?);
    }
    let tmp = options.out.with_extension("mcap.partial");
    std::fs::copy(&options.file, &tmp)
        .with_context(|| format!("cannot copy {} to {}", options.file.display(), tmp.display()))?;
    let result = rewrite_session(&tmp, ReadOptions::default(), &|_| false, channels);
    if let Err(e) = result {
        let _ = std::fs::remove_file(&tmp);
        return Err(e.into());
    }
    std::fs::rename(&tmp, &options.out).with_context(|| format!("cannot write {}", options.out.display()))?;
    Ok(ReplayedFile { estimates, with_model: model.is_some() })
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
