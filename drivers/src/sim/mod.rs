//! The simulated rig: a physics model of the grasp and the sensors behind every device trait.

pub mod camera;
