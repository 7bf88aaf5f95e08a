#![doc = include_str!("../README.md")]
#![warn(missing_docs)]

pub mod bench;
pub mod camera_calibration;
pub mod channels;
pub mod collect_vision;
pub mod dataset;
pub mod dekf_eval;
pub mod dekf_run;
pub mod dekf_train;
pub mod devices;
#[cfg(all(feature = "devices", target_os = "linux"))]
pub mod emulate;
pub mod grasp_eval;
pub mod grasp_state;
pub mod hand_calibration;
pub mod hand_calibration_session;
pub mod hand_target;
pub mod image_encoder;
pub mod image_markers;
pub mod import;
pub mod labelling;
pub mod linear_baseline;
pub mod live_view;
pub mod marker;
pub mod observer;
#[cfg(test)]
mod observer_encoding_tests;
pub mod outlets;
pub mod pipeline;
pub mod planar_eval;
pub mod plot;
pub mod protocol;
pub mod record;
pub mod replay;
pub mod replay_file;
pub mod rig;
pub mod rig_config;
pub mod ros2_play;
pub mod study;
pub mod tactile_force;
pub mod tracked_trial;
pub mod tracking;
pub mod trial;
pub mod trial_inputs;
#[cfg(all(feature = "devices", target_os = "linux"))]
pub mod v4l2_intrinsics;
pub mod vision;
pub mod vision_inhand;
pub mod vision_sim;
