//! `slidetrack import`: recordings made elsewhere turned into sessions
//! (the library code is `slidetrack_experiment::import`).

use anyhow::{Context, Result};
use serde_json::json;
use slidetrack_experiment::import::xela_csv::{find_sequences, read_sequence};
use slidetrack_experiment::import::xela_session::{ImportOptions, import_sequence};
use slidetrack_experiment::import::{xela_psc, xela_psc_session};

use crate::cli::{ImportArgs, ImportCommand, RecordingDirsArgs};

pub fn run(args: &ImportArgs, quiet: bool) -> Result<()> {
    match &args.what {
        ImportCommand::XelaCsv(a) => xela_csv(a, quiet),
        ImportCommand::XelaPsc(a) => xela_psc(a, quiet),
    }
}

/// Each sequence is read whole (every file checked) before its session is
/// written, so a malformed file stops the import with nothing written for it.
fn xela_csv(args: &RecordingDirsArgs, quiet: bool) -> Result<()> {
    let dirs = find_sequences(&args.dirs)?;
    std::fs::create_dir_all(&args.out).with_context(|| format!("cannot create {}", args.out.display()))?;
    let options = ImportOptions { overwrite: args.overwrite };
    for dir in &dirs {
        let seq = read_sequence(dir)?;
        let r = import_sequence(&seq, dir, &args.out, options)?;
        if args.json {
            let v = json!({
                "session": r.path,
                "source": dir,
                "rows": r.rows,
                "shared_rows": r.shared_rows,
                "tactile_refreshes": r.fresh_scans,
                "marker_rows_seen": r.markers_seen,
                "duration_s": r.duration_s,
                "object": seq.meta.object_name,
                "dropped": seq.meta.dropped,
            });
            println!("{v}");
        } else if !quiet {
            println!(
                "{}: {} rows over {:.2} s ({} tactile refreshes; marker 1 on {} rows, marker 2 on {}); object {}{}",
                r.path.display(),
                r.rows,
                r.duration_s,
                r.fresh_scans,
                r.markers_seen[0],
                r.markers_seen[1],
                seq.meta.object_name,
                if seq.meta.dropped { ", dropped" } else { "" }
            );
        }
    }
    Ok(())
}

/// As [`xela_csv`]: each trial is read whole before its session is written.
fn xela_psc(args: &RecordingDirsArgs, quiet: bool) -> Result<()> {
    let dirs = xela_psc::find_sequences(&args.dirs)?;
    std::fs::create_dir_all(&args.out).with_context(|| format!("cannot create {}", args.out.display()))?;
    let options = ImportOptions { overwrite: args.overwrite };
    for dir in &dirs {
        let seq = xela_psc::read_sequence(dir)?;
        let r = xela_psc_session::import_sequence(&seq, dir, &args.out, options)?;
        if args.json {
            let v = json!({
                "session": r.path,
                "source": dir,
                "rows": r.rows,
                "shared_rows": r.shared_rows,
                "tactile_refreshes": r.fresh_scans,
                "marker_rows_seen": r.marker_seen,
                "slip_rows": r.slip_rows,
                "fail_rows": r.fail_rows,
                "duration_s": r.duration_s,
                "rate_hz": r.rate_hz,
                "dropped": seq.meta.dropped,
            });
            println!("{v}");
        } else if !quiet {
            println!(
                "{}: {} rows over {:.2} s ({:.1} Hz; {} tactile refreshes; marker on {} rows; {} slip rows, {} fail rows){}",
                r.path.display(),
                r.rows,
                r.duration_s,
                r.rate_hz,
                r.fresh_scans,
                r.marker_seen,
                r.slip_rows,
                r.fail_rows,
                if seq.meta.dropped { ", dropped" } else { "" }
            );
        }
    }
    Ok(())
}
