//! `slidetrack eval`: the dEKF's errors on sessions against their truth
//! (Table 6.1), beside predicting no motion and the linear-map baseline.

use anyhow::Result;
use serde_json::json;
use slidetrack_experiment::dataset::expand;
use slidetrack_experiment::dekf_eval::{evaluate, table};
use slidetrack_experiment::dekf_run::load_model;
use slidetrack_experiment::dekf_train::model_options::StateKind;
use slidetrack_experiment::linear_baseline::LinearBaseline;
use slidetrack_experiment::planar_eval::{evaluate_planar, planar_table};

use crate::cli::EvalArgs;

pub fn run_cmd(args: &EvalArgs) -> Result<()> {
    let model = load_model(&args.model)?;
    let files = expand(&args.files)?;
    let linear = match &args.linear {
        Some(path) => Some(LinearBaseline::load(path)?),
        None => LinearBaseline::beside(&model, &args.model)?,
    };
    let mut v = match model.state() {
        StateKind::Sliding => {
            let report = evaluate(&model, &files, args.truth.into(), linear.as_ref())?;
            if !args.json {
                print!("{}", table(&report));
            }
            serde_json::to_value(&report)?
        }
        StateKind::Planar => {
            let report = evaluate_planar(&model, &files, linear.as_ref())?;
            if !args.json {
                print!("{}", planar_table(&report));
            }
            serde_json::to_value(&report)?
        }
    };
    if args.json {
        v["model"] = json!(args.model);
        v["state"] = json!(model.state());
        println!("{}", serde_json::to_string_pretty(&v)?);
    }
    Ok(())
}
