//! V4L2 cameras (`[hw.camera] kind = "v4l2"`) and RGB-D pairs of them.
//!
//! - [`config`]: the `[hw.camera]` table; [`rgbd_config`] the `[rgbd]`
//!   camera pair.
//! - [`decode`] and [`mjpeg`] (no I/O): what a captured buffer holds, JPEG
//!   and YUYV decoding, 16-bit depth to PNG.
//! - `backend` (feature `devices`, Linux): `V4l2Camera`, streaming from a
//!   device node.

pub mod config;
pub mod decode;
pub mod mjpeg;
pub mod rgbd_config;

pub use decode::{CaptureCounters, FrameLayout, frame_content};

#[cfg(all(feature = "devices", target_os = "linux"))]
pub mod backend;
