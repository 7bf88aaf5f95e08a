//! `slidetrack eval`: the dEKF's errors on sessions against their truth
//! (Table 6.1), beside the zero-motion baseline.

use anyhow::Result;
use serde_json::json;
use slidetrack_experiment::dataset::expand;
use slidetrack_experiment::dekf_eval::{evaluate, table};
use slidetrack_experiment::dekf_run::load_model;

use crate::cli::EvalArgs;

pub fn run_cmd(args: &EvalArgs) -> Result<()> {
    let model = load_model(&args.model)?;
    let files = expand(&args.files)?;
    let report = evaluate(&model, &files, args.truth.into())?;
    if args.json {
        let mut v = serde_json::to_value(&report)?;
        v["model"] = json!(args.model);
        println!("{}", serde_json::to_string_pretty(&v)?);
    } else {
        print!("{}", table(&report));
    }
    Ok(())
}
