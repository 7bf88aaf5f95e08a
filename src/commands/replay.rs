//! `slidetrack replay`: run a dEKF model over a recorded session and write a
//! copy of it with the model's input and estimates.

use anyhow::{Context, Result, bail};
use slidetrack_experiment::dataset::{TruthSource, load};
use slidetrack_experiment::dekf_run::{CM, estimate_message, estimate_metadata, load_model, run};
use slidetrack_experiment::plot::{PALETTE, Panel, Series, draw_stacked};
use slidetrack_session::{DekfEstimate, NewChannel, ReadOptions, TactileDerivative, rewrite_session};

use crate::cli::ReplayArgs;

pub fn run_cmd(args: &ReplayArgs) -> Result<()> {
    let model = load_model(&args.model)?;
    let data = load(&args.file, None)?;
    let outputs = run(&model, &data)?;
    if args.out.exists() && !args.overwrite {
        bail!("{} already exists; pass --overwrite to replace it", args.out.display());
    }
    if std::fs::canonicalize(&args.file).ok() == std::fs::canonicalize(&args.out).ok() {
        bail!("--out must differ from the input file");
    }
    let model_name = args.model.file_name().map_or(String::new(), |n| n.to_string_lossy().into_owned());
    let [derivative_meta, estimate_meta] = estimate_metadata(&model, &model_name)?;
    let mut derivative = NewChannel::of::<TactileDerivative>(derivative_meta);
    let mut estimate = NewChannel::of::<DekfEstimate>(estimate_meta);
    for (t, o) in &outputs {
        derivative.push_json(*t, &TactileDerivative { values: o.measurement.clone() })?;
        estimate.push_json(*t, &estimate_message(o))?;
    }
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
        plot_replay(args, &outputs)?;
        println!("{}", plot.display());
    }
    Ok(())
}

/// Estimated position and velocity against the ground truth and the
/// simulator's truth when present (Fig. 6.9).
fn plot_replay(
    args: &ReplayArgs,
    outputs: &[(slidetrack_core::TimeNs, slidetrack_estimators::dekf::DekfOutput)],
) -> Result<()> {
    let Some(out) = &args.plot else { return Ok(()) };
    let t0 = outputs.first().map_or(0.0, |(t, _)| t.as_secs_f64());
    let mut pos = vec![Series::line(
        "dEKF estimate",
        PALETTE[3],
        outputs.iter().map(|(t, o)| (t.as_secs_f64(), o.mean[0])).collect(),
    )];
    let mut vel = vec![Series::line(
        "dEKF estimate",
        PALETTE[3],
        outputs.iter().map(|(t, o)| (t.as_secs_f64(), o.mean[1])).collect(),
    )];
    for (source, label, colour) in [
        (TruthSource::GroundTruth, "ground truth", PALETTE[0]),
        (TruthSource::Sim, "simulator truth", PALETTE[2]),
    ] {
        if let Ok(d) = load(&args.file, Some(source)) {
            let truth = d.truth.unwrap_or_default();
            let start = d.times.iter().position(|t| t.as_secs_f64() >= t0).unwrap_or(0);
            let origin = truth.get(start).map_or(0.0, |x| x[0]);
            pos.insert(
                0,
                Series::line(
                    label,
                    colour,
                    d.times
                        .iter()
                        .zip(&truth)
                        .map(|(t, x)| (t.as_secs_f64(), (x[0] - origin) * CM))
                        .collect(),
                ),
            );
            vel.insert(
                0,
                Series::line(
                    label,
                    colour,
                    d.times.iter().zip(&truth).map(|(t, x)| (t.as_secs_f64(), x[1] * CM)).collect(),
                ),
            );
        }
    }
    let name = args.file.file_name().map_or(String::new(), |n| n.to_string_lossy().into_owned());
    draw_stacked(
        out,
        &format!("{name}: dEKF replay"),
        &[
            Panel { title: "position along the sliding axis".into(), y_label: "cm".into(), series: pos },
            Panel { title: "velocity along the sliding axis".into(), y_label: "cm/s".into(), series: vel },
        ],
    )
}
