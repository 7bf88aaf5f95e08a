//! `slidetrack replay`: run a dEKF model over a recorded session (through the
//! replay rig, as `track` runs it live) and write a copy of the session with
//! the model's input and estimates.

use anyhow::{Context, Result, bail};
use slidetrack_experiment::dataset::load;
use slidetrack_experiment::dekf_eval::has_protocol;
use slidetrack_experiment::dekf_run::{estimate_channel, estimate_metadata, load_model, run};
use slidetrack_experiment::plot::dekf::plot_replay;
use slidetrack_experiment::replay::replay_dekf;
use slidetrack_session::{NewChannel, ReadOptions, TactileDerivative, rewrite_session};

use crate::cli::ReplayArgs;

pub fn run_cmd(args: &ReplayArgs) -> Result<()> {
    let model = load_model(&args.model)?;
    if args.out.exists() && !args.overwrite {
        bail!("{} already exists; pass --overwrite to replace it", args.out.display());
    }
    if std::fs::canonicalize(&args.file).ok() == std::fs::canonicalize(&args.out).ok() {
        bail!("--out must differ from the input file");
    }
    // Sessions recorded without the protocol (imports) have nothing to
    // replay it on: the model runs over their recorded zeroed scans.
    let outputs = if has_protocol(&args.file)? {
        replay_dekf(&args.file, &model)?
    } else {
        run(&model, &load(&args.file, None)?)?
    };
    let model_name = args.model.file_name().map_or(String::new(), |n| n.to_string_lossy().into_owned());
    let [derivative_meta, estimate_meta] = estimate_metadata(&model, &model_name)?;
    let mut derivative = NewChannel::of::<TactileDerivative>(derivative_meta);
    for (t, o) in &outputs {
        derivative.push_json(*t, &TactileDerivative { values: o.measurement.clone() })?;
    }
    let estimate = estimate_channel(&model, estimate_meta, &outputs)?;
    let tmp = args.out.with_extension("mcap.partial");
    std::fs::copy(&args.file, &tmp)
        .with_context(|| format!("cannot copy {} to {}", args.file.display(), tmp.display()))?;
    let result = rewrite_session(&tmp, ReadOptions::default(), &|_| false, vec![derivative, estimate]);
    if let Err(e) = result {
        let _ = std::fs::remove_file(&tmp);
        return Err(e.into());
    }
    std::fs::rename(&tmp, &args.out).with_context(|| format!("cannot write {}", args.out.display()))?;
    println!("{}: {} dEKF steps", args.out.display(), outputs.len());
    if let Some(plot) = &args.plot {
        plot_replay(&args.file, &outputs, plot)?;
        println!("{}", plot.display());
    }
    Ok(())
}
