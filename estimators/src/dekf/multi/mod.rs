//! The dEKF for a state of several degrees of freedom (planar slip: two
//! translations in the contact plane and the rotation about its normal,
//! with their rates): the thesis's filter, loss and training with vectors
//! where it has scalars. The one-dimensional filter of [`super::ekf`] and
//! [`super::batch_grad`] stays the thesis's, untouched; its equivalence with
//! this one at one degree of freedom is tested in [`ekf`].

pub mod bptt;
pub mod ekf;
mod filter;

pub use filter::MultiFilter;

#[cfg(test)]
mod tests;
