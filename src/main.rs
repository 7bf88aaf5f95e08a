//! `slidetrack`: controlled-sliding experiments, sessions and trackers from the command line.

mod cli;
mod commands;

use std::process::ExitCode;

use clap::Parser;

fn main() -> ExitCode {
    quiet_closed_stdout();
    let cli = cli::Cli::parse();
    let level = match (cli.quiet, cli.verbose) {
        (true, _) => "error",
        (false, 0) => "warn",
        (false, 1) => "info",
        (false, _) => "debug",
    };
    // The Foxglove SDK reports each message it could not send to a viewer
    // that went away: one line per message. The live view's own summary
    // says what matters; -vv shows the SDK's lines.
    // RustDDS (--ros2) likewise logs its own shutdown (a discovery writer it
    // could not remove once its event loop stopped) as errors; the ROS 2
    // summary says what was published and dropped; -vv shows RustDDS's lines.
    let foxglove = if cli.verbose >= 2 { "" } else { ",foxglove=off,rustdds=off" };
    let filter = tracing_subscriber::EnvFilter::try_from_default_env()
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new(format!("{level}{foxglove}")));
    tracing_subscriber::fmt().with_env_filter(filter).with_writer(std::io::stderr).without_time().init();
    match commands::dispatch::dispatch(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {}", one_line(&e));
            ExitCode::FAILURE
        }
    }
}

/// `println!` panics when standard output is closed (`slidetrack label ... |
/// head -1`). Say so in one line instead of a panic report with a backtrace;
/// the unwinding that follows still closes sessions and releases devices as
/// an error would. (Restoring SIGPIPE's default action instead would kill
/// the process at once, without that.)
fn quiet_closed_stdout() {
    let report = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        let message = info.payload_as_str().unwrap_or_default();
        if message.starts_with("failed printing to stdout") && message.contains("Broken pipe") {
            eprintln!("slidetrack: standard output was closed; stopping");
        } else {
            report(info);
        }
    }));
}

/// The error and its causes on one line, skipping a cause whose text the
/// message before it already contains (library errors often quote their source).
fn one_line(e: &anyhow::Error) -> String {
    let mut line = String::new();
    for cause in e.chain() {
        let text = cause.to_string();
        if line.contains(&text) {
            continue;
        }
        if !line.is_empty() {
            line.push_str(": ");
        }
        line.push_str(&text);
    }
    line
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn causes_already_quoted_are_not_repeated() {
        let io = std::io::Error::new(std::io::ErrorKind::AlreadyExists, "File exists");
        let e = anyhow::Error::new(io).context("cannot create x.mcap: File exists").context("trial 3");
        assert_eq!(one_line(&e), "trial 3: cannot create x.mcap: File exists");
    }
}
