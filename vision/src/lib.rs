#![doc = include_str!("../README.md")]
#![warn(missing_docs)]
//!
//! # Running a tracker online
//!
//! ```no_run
//! use slidetrack_vision::{ObjectModel, TrackerKind, TrackerSettings, build_tracker};
//! use slidetrack_vision::sources::{MeasurementSource, SlowNetwork, SlowNetworkConfig};
//! # fn frames() -> Vec<slidetrack_core::RgbdFrame> { Vec::new() }
//! # fn run(intrinsics: slidetrack_core::CameraIntrinsics) -> Result<(), slidetrack_vision::VisionError> {
//! let model = ObjectModel::load("mustard/points.xyz".as_ref(), 1.0)?;
//! let mut tracker = build_tracker(TrackerKind::Roft, &model, &intrinsics, &TrackerSettings::default())?;
//! let mut network = SlowNetwork::new(SlowNetworkConfig::default()); // or a FileSequence, SessionMeasurements...
//! for frame in frames() {
//!     let arrivals = network.on_frame(frame.t, None)?;
//!     if let Some(state) = tracker.process(&frame, &arrivals)? {
//!         println!("{:?}", state.estimate.camera_from_object);
//!     }
//! }
//! # Ok(()) }
//! ```

pub mod cloud;
mod error;
pub mod eval;
pub mod flow;
pub mod input;
pub mod live;
pub mod model;
pub mod online;
pub mod record;
pub mod sources;

pub use error::VisionError;
pub use model::ObjectModel;
pub use online::{
    MaskUkfTracker, OnlineTracker, PoseReset, RoftTracker, StepNote, TrackedState, TrackerKind,
    TrackerSettings, build_tracker,
};
