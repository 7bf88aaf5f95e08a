//! `slidetrack export`: one channel as CSV on stdout, or the session as a ROS 2 bag.

use std::io::Write;
use std::path::Path;

use anyhow::{Context, Result};
use slidetrack_session::{ReadOptions, export_csv, export_ros2_bag};

use crate::cli::ExportArgs;

pub fn run(args: &ExportArgs) -> Result<()> {
    let options = ReadOptions { recover: args.recover };
    if let Some(out) = &args.ros2_bag {
        return ros2_bag(&args.file, out, options);
    }
    let channel = args.channel.as_deref().context("export: give --channel or --ros2-bag")?;
    let stdout = std::io::stdout();
    let mut out = std::io::BufWriter::new(stdout.lock());
    let summary = export_csv(&args.file, channel, options, &mut out)?;
    out.flush()?;
    tracing::info!("{} rows, {} columns", summary.rows, summary.columns.len());
    Ok(())
}

fn ros2_bag(session: &Path, out: &Path, options: ReadOptions) -> Result<()> {
    let report = export_ros2_bag(session, out, options)?;
    let written: u64 = report.written.values().sum();
    tracing::info!("{}: {written} messages on {} topics", out.display(), report.written.len());
    if !report.left_out.is_empty() {
        let topics: Vec<&str> = report.left_out.keys().map(String::as_str).collect();
        tracing::info!("left out (no ROS 2 type): {}", topics.join(", "));
    }
    Ok(())
}
