//! `slidetrack export`: one channel as CSV on stdout.

use std::io::Write;

use anyhow::Result;
use slidetrack_session::{ReadOptions, export_csv};

use crate::cli::ExportArgs;

pub fn run(args: &ExportArgs) -> Result<()> {
    let stdout = std::io::stdout();
    let mut out = std::io::BufWriter::new(stdout.lock());
    let summary = export_csv(&args.file, &args.channel, ReadOptions { recover: args.recover }, &mut out)?;
    out.flush()?;
    tracing::info!("{} rows, {} columns", summary.rows, summary.columns.len());
    Ok(())
}
