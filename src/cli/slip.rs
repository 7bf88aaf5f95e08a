//! Arguments of `slip`: the grasp-state detector scored on recorded sessions.

use std::path::PathBuf;

use clap::Args;

/// Arguments of `slip`.
#[derive(Debug, Args, Clone, PartialEq)]
pub struct SlipArgs {
    /// Session files (.mcap), or directories of them.
    #[arg(required = true)]
    pub files: Vec<PathBuf>,
    /// Print the report as JSON instead of tables.
    #[arg(long)]
    pub json: bool,
}
