#![doc = include_str!("../README.md")]
#![warn(missing_docs)]

pub mod aruco;
pub mod axis;
pub mod board;
pub mod calibrate;
pub mod calibrate_live;
pub mod camera_info;
pub mod codec;
pub mod error;
pub mod ground_truth;
pub mod hand_eye;
pub mod hand_eye_error;
pub mod hand_frame;
pub mod in_hand;
pub mod label;
pub mod marker_tool;
pub mod pose;
pub mod session_inputs;
pub mod tactile_force;

#[cfg(test)]
mod hand_eye_sim_tests;
#[cfg(test)]
mod sim_tests;

pub use aruco::{
    CornerRefinement, Dictionary, MarkerDetection, MarkerDetector, MarkerTracker, PixelRoi, marker_pattern,
};
pub use axis::{SlidingAxis, SlidingProjector};
pub use board::{Board, BoardObservation, BoardPose, board_patterns, board_pose};
pub use codec::encode_jpeg;
pub use error::MarkerError;
pub use pose::{MarkerPose, marker_pose, marker_pose_candidates};

/// Makes OpenCV run its functions on the calling thread only (benchmarks on one core).
pub fn use_one_thread() {
    if let Err(e) = opencv::core::set_num_threads(1) {
        tracing::warn!("cannot limit OpenCV to one thread: {e}");
    }
}
