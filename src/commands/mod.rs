//! One module per subcommand, `dispatch` routing to them, and what several
//! commands share (the stop flag).

mod aruco;
mod bench;
mod calibrate;
mod calibrate_tactile;
mod collect;
mod decode;
mod demo;
#[cfg(all(feature = "devices", target_os = "linux"))]
mod devices;
pub mod dispatch;
#[cfg(all(feature = "devices", target_os = "linux"))]
mod emulate;
pub mod eval;
mod export;
mod import;
mod info;
mod label;
mod live;
mod objects;
mod play;
mod plot;
mod record;
pub mod replay;
mod slip;
pub mod study;
pub mod track;
pub mod train;
pub mod vision;

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, OnceLock};

/// The error of a command that needs the device backends in a build without them.
#[cfg(not(all(feature = "devices", target_os = "linux")))]
pub fn without_devices(what: &str) -> anyhow::Error {
    anyhow::anyhow!(
        "{what} needs the real devices' backends, and this slidetrack was built without them \
         (the `devices` feature, Linux only)"
    )
}

/// What a trial does when stopped: `stop_flag`'s message for commands that drive the hand.
pub const RELEASING: &str = "releasing the hand and closing the session";

/// A flag that turns true on Ctrl-C (SIGINT) or SIGTERM, so that a running
/// command ends cleanly (a trial releases the hand and finishes its session
/// file) before exiting; `stopping` says what it does then (one command per
/// process: the first caller's words stand).
pub fn stop_flag(stopping: &'static str) -> Arc<AtomicBool> {
    static FLAG: OnceLock<Arc<AtomicBool>> = OnceLock::new();
    FLAG.get_or_init(|| {
        let flag = Arc::new(AtomicBool::new(false));
        let f = flag.clone();
        if let Err(e) = ctrlc::set_handler(move || {
            if f.swap(true, Ordering::SeqCst) {
                // Second Ctrl-C: the user insists.
                std::process::exit(130);
            }
            eprintln!("\nstopping: {stopping} (Ctrl-C again to quit at once)");
        }) {
            tracing::warn!("cannot install the Ctrl-C handler: {e}");
        }
        flag
    })
    .clone()
}
