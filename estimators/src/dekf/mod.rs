//! The differentiable Extended Kalman filter of thesis Chapter 6: tracks the
//! position and velocity of an object sliding in the hand from the
//! derivative of the tactile signal.

mod batch;
mod bptt;
pub mod ekf;
pub mod file;
mod filter;
mod infer;
mod input;
pub mod mlp;
mod model;
pub mod multi;
pub mod params;
mod parts;
mod state;
mod thin;
mod train;

pub use batch::{BatchGrad, Sequence, Window};
pub use bptt::batch_grad;
pub use ekf::MIN_INNOVATION_VAR;
pub use filter::{DekfOutput, DekfTracker};
pub use input::{DekfInput, InputStep};
pub use model::{DekfModel, Measurement, ModelMeta};
pub use params::{Activation, Architecture};
pub use parts::DEFAULT_PART_WINDOWS;
pub use state::StateKind;
pub use train::{
    Batching, EpochReport, Progress, Selection, Stage, TrainConfig, train, train_with_selection,
};

#[cfg(test)]
mod golden;
#[cfg(test)]
mod tests;
