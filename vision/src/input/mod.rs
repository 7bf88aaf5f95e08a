//! RGB-D inputs: recorded sessions ([`SessionRgbd`]), YCB-Video-style
//! directories of PNGs ([`YcbDirectory`]) and live cameras, a colour camera paired with a Z16 depth camera
//! ([`CameraPair`], for example two V4L2 devices, or a recording replayed
//! in real time as two cameras, [`RecordedRgbd`], with its truth
//! [`RecordedTruth`]), and depth registered to the colour camera
//! ([`register_depth_to_color`]).

mod camera_pair;
pub(crate) mod codec;
mod recorded;
mod recorded_truth;
pub mod registration;
mod session;
mod source;
mod ycb;

pub use camera_pair::{CameraPair, DepthRegistration, Pacer, PairCounts, PairSettings};
pub use codec::{decode_color, decode_depth, encode_color_jpeg, encode_depth_png};
pub use recorded::{RecordedCamera, RecordedRgbd, ReplayCounts, ReplayOptions};
pub use recorded_truth::RecordedTruth;
pub use registration::register_depth_to_color;
pub use session::SessionRgbd;
pub use source::{RgbdSample, RgbdSource};
pub use ycb::{YCB_CLASSES, YcbDirectory, YcbMeta, read_meta};
