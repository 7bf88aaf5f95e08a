#![doc = include_str!("../README.md")]
#![warn(missing_docs)]
//!
//! - [`LiveServer`] serves what a [`slidetrack_session::Recorder`] writes:
//!   give [`LiveServer::tap`] to [`slidetrack_session::RecorderOptions::live`].
//! - [`play`] serves a recorded session at its recorded timing.
//! - [`StalledViewer`] is a viewer that subscribes to everything and never
//!   reads, for benchmarks and tests of the recorder's independence.

mod address;
mod background;
mod error;
mod front_door;
mod player;
mod player_clock;
mod probe;
mod publisher;
mod server;

pub use address::{DEFAULT_LIVE_ADDR, resolve_addr};
pub use error::LiveError;
pub use player::{PlayOptions, PlayReport, play};
pub use probe::StalledViewer;
pub use server::{LiveOptions, LiveServer, LiveStats};
