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

#[cfg(test)]
mod tests {
    use std::path::PathBuf;

    use clap::Parser;

    use super::super::{Cli, Command};

    #[test]
    fn slip_takes_files_and_json() {
        let cli = Cli::try_parse_from(["slidetrack", "slip", "a.mcap", "dir", "--json"]).unwrap();
        let Command::Slip(a) = cli.command else { panic!("not slip") };
        assert_eq!(a.files, [PathBuf::from("a.mcap"), PathBuf::from("dir")]);
        assert!(a.json);
        assert!(Cli::try_parse_from(["slidetrack", "slip"]).is_err(), "a file is required");
    }
}
