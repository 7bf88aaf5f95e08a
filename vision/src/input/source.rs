//! What every RGB-D input gives: frames with their truth, in acquisition order.

use slidetrack_core::{CameraIntrinsics, ObjectTruth, RgbdFrame};
use slidetrack_estimators::roft::Mask;

use crate::VisionError;

/// One frame of an input, with the truth that comes with it (simulated
/// sessions and annotated datasets).
#[derive(Clone, Debug)]
pub struct RgbdSample {
    /// The frame.
    pub frame: RgbdFrame,
    /// The object's true pose and velocity.
    pub truth: Option<ObjectTruth>,
    /// The object's true mask.
    pub truth_mask: Option<Mask>,
}

/// A source of RGB-D frames.
///
/// # Contract
/// `next` returns frames in acquisition order, `Ok(None)` at the end (live
/// cameras: when no frame is ready yet is not the end — they block until
/// one is). Every frame has the source's intrinsics and size.
pub trait RgbdSource {
    /// The intrinsics of every frame.
    fn intrinsics(&self) -> &CameraIntrinsics;
    /// The next frame.
    fn next_frame(&mut self) -> Result<Option<RgbdSample>, VisionError>;
    /// Number of frames, when known.
    fn len_hint(&self) -> Option<usize> {
        None
    }
}
