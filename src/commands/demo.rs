//! `slidetrack demo`: a few simulated trials, what they recorded, and plots.

use anyhow::Result;
use slidetrack_drivers::session::{ReadOptions, SessionInfo};

use crate::cli::{CollectArgs, DemoArgs, PlotArgs, PlotKind, RigKind};

pub fn run(args: &DemoArgs, quiet: bool) -> Result<()> {
    println!("slidetrack demo: one controlled-sliding trial per object on the simulated rig\n");
    for object in ["box", "bottle", "mustard"] {
        let collect = CollectArgs {
            rig: RigKind::Sim,
            object: object.into(),
            trials: 1,
            first_trial: 0,
            duration: args.duration,
            seed: args.seed,
            out: args.out.join("sessions"),
            config: None,
            no_camera: false,
            realtime: false,
            overwrite: true,
        };
        let reports = super::collect::collect(&collect, quiet)?;
        for report in &reports {
            let info = SessionInfo::read(&report.path, ReadOptions::default())?;
            println!(
                "  recorded {:.1} MB in {:.1} s of wall time ({:.0}x real time): {}",
                info.file_size_bytes as f64 / 1e6,
                report.wall_s,
                report.outcome.end.as_secs_f64() / report.wall_s.max(1e-9),
                info.channels
                    .iter()
                    .map(|c| format!("{} {}", c.topic, c.message_count))
                    .collect::<Vec<_>>()
                    .join(", ")
            );
            let stem =
                report.path.file_stem().map_or_else(|| object.into(), |s| s.to_string_lossy().into_owned());
            for (kind, suffix) in [(PlotKind::Overview, "overview"), (PlotKind::Grasp, "grasp")] {
                let out = args.out.join(format!("{stem}-{suffix}.png"));
                super::plot::run(&PlotArgs { file: report.path.clone(), out, what: kind, recover: false })?;
            }
        }
        println!();
    }
    println!("sessions and plots are in {}", args.out.display());
    println!(
        "next: `slidetrack info FILE`, `slidetrack export FILE --channel /tactile/raw`, or open a .mcap in Foxglove"
    );
    Ok(())
}
