#![doc = include_str!("../README.md")]
#![warn(missing_docs)]

mod pi;
mod protocol;
mod reference;
mod runner;
mod safety;

pub use pi::{PiConfig, PiController, PiOutput};
pub use protocol::{
    Baseline, ControlRecord, HandAction, Protocol, ProtocolConfig, ProtocolEvent, ProtocolSettings,
    ScanOutput, Tare,
};
pub use reference::{GraspProfile, partition};
pub use runner::{ObserverError, Rig, TrialObserver, TrialOutcome, run_trial};
pub use safety::{AbortReason, SafetyConfig};
