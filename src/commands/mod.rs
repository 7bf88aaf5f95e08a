//! One module per subcommand; `dispatch` routes to them.

mod bench;
mod collect;
mod demo;
mod export;
mod info;
mod objects;
mod plot;

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, OnceLock};

use anyhow::Result;

use crate::cli::{Cli, Command};

/// Runs the command the user asked for.
pub fn dispatch(cli: Cli) -> Result<()> {
    let quiet = cli.quiet;
    match cli.command {
        Command::Collect(args) => collect::run(&args, quiet),
        Command::Info(args) => info::run(&args),
        Command::Export(args) => export::run(&args),
        Command::Plot(args) => plot::run(&args),
        Command::Demo(args) => demo::run(&args, quiet),
        Command::Bench(args) => bench::run(&args),
        Command::Objects => objects::run(),
    }
}

/// A flag that turns true on Ctrl-C (SIGINT) or SIGTERM, so that a running
/// trial releases the hand and finishes its session file before exiting.
pub fn stop_flag() -> Arc<AtomicBool> {
    static FLAG: OnceLock<Arc<AtomicBool>> = OnceLock::new();
    FLAG.get_or_init(|| {
        let flag = Arc::new(AtomicBool::new(false));
        let f = flag.clone();
        if let Err(e) = ctrlc::set_handler(move || {
            if f.swap(true, Ordering::SeqCst) {
                // Second Ctrl-C: the user insists.
                std::process::exit(130);
            }
            eprintln!(
                "\nstopping: releasing the hand and closing the session (Ctrl-C again to quit at once)"
            );
        }) {
            tracing::warn!("cannot install the Ctrl-C handler: {e}");
        }
        flag
    })
    .clone()
}
