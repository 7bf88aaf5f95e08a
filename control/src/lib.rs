#![doc = include_str!("../README.md")]
#![warn(missing_docs)]

mod gripper;
mod pi;
mod protocol;
mod reference;
mod runner;
mod safety;
mod spike_gate;

pub use gripper::{GripperControlConfig, GripperGrasp};
pub use pi::{PiConfig, PiController, PiLaw, PiOutput};
pub use protocol::{
    Baseline, ControlRecord, HandAction, Protocol, ProtocolConfig, ProtocolEvent, ProtocolSettings,
    ScanOutput, Tare,
};
pub use reference::{GraspProfile, partition, partition_two_opposed};
pub use runner::{ObserverError, Rig, TrialObserver, TrialOutcome, run_trial};
pub use safety::{AbortReason, SafetyConfig};
pub use spike_gate::{ZSpikeGate, ZSpikeGateConfig};
