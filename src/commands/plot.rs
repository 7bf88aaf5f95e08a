//! `slidetrack plot`: pictures of a session.

use anyhow::Result;
use slidetrack_experiment::plot::draw_stacked;
use slidetrack_experiment::plot::ground_truth::ground_truth_panels;
use slidetrack_experiment::plot::session::{grasp_overview, grasp_panels, position_panel, tactile_panels};
use slidetrack_session::ReadOptions;

use crate::cli::{PlotArgs, PlotKind};

pub fn run(args: &PlotArgs) -> Result<()> {
    let opts = ReadOptions { recover: args.recover };
    let panels = match args.what {
        PlotKind::GroundTruth => ground_truth_panels(&args.file, opts)?,
        PlotKind::Grasp => grasp_panels(&args.file, opts)?,
        PlotKind::Tactile => {
            let mut p = tactile_panels(&args.file, opts)?;
            p.push(position_panel(&args.file, opts)?);
            p
        }
        PlotKind::Overview => {
            let mut p = vec![grasp_overview(&args.file, opts)?];
            p.extend(tactile_panels(&args.file, opts)?);
            p.push(position_panel(&args.file, opts)?);
            p
        }
    };
    let name = args.file.file_name().map_or_else(String::new, |n| n.to_string_lossy().into_owned());
    draw_stacked(&args.out, &name, &panels)?;
    println!("{}", args.out.display());
    Ok(())
}
