//! What a source of masks and poses hands over, and the trait every source
//! implements.

use nalgebra::Isometry3;
use slidetrack_core::{RgbdFrame, TimeNs};
use slidetrack_estimators::roft::Mask;

use crate::VisionError;

/// A measurement computed on an earlier frame.
#[derive(Clone, Debug, PartialEq)]
pub struct Delayed<T> {
    /// The time of the frame it was computed on.
    pub frame_t: TimeNs,
    /// When it became available.
    pub arrival_t: TimeNs,
    /// The measurement.
    pub value: T,
}

/// What arrived by a frame.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Arrivals {
    /// Masks, oldest first.
    pub masks: Vec<Delayed<Mask>>,
    /// Poses (`camera_from_object`), oldest first.
    pub poses: Vec<Delayed<Isometry3<f64>>>,
}

impl Arrivals {
    /// The newest mask.
    pub fn latest_mask(&self) -> Option<&Delayed<Mask>> {
        self.masks.last()
    }

    /// The newest pose.
    pub fn latest_pose(&self) -> Option<&Delayed<Isometry3<f64>>> {
        self.poses.last()
    }
}

/// The ground truth of a frame, for sources that imitate networks.
#[derive(Clone, Copy, Debug)]
pub struct FrameTruth<'a> {
    /// True `camera_from_object`.
    pub camera_from_object: &'a Isometry3<f64>,
    /// True mask.
    pub mask: &'a Mask,
}

/// A source of masks and poses.
///
/// # Contract
/// `on_frame` (or `on_rgbd_frame`, which sources that look at the images
/// implement) is called once per RGB-D frame, with increasing `t`, and the
/// frame's ground truth when the input has one. It returns what became
/// available at or before `t` and was not returned yet. It does not block
/// on I/O (the ArUco source computes in the caller's thread; the external
/// source waits only as long as it is told to).
pub trait MeasurementSource: Send {
    /// The measurements available at frame `t`.
    fn on_frame(&mut self, t: TimeNs, truth: Option<FrameTruth<'_>>) -> Result<Arrivals, VisionError>;

    /// The measurements available at `frame`, for sources that need its
    /// images; the others answer as [`MeasurementSource::on_frame`] at its time.
    fn on_rgbd_frame(
        &mut self,
        frame: &RgbdFrame,
        truth: Option<FrameTruth<'_>>,
    ) -> Result<Arrivals, VisionError> {
        self.on_frame(frame.t, truth)
    }

    /// A one-line account of what the source did (counts), for reports.
    fn summary(&self) -> Option<String> {
        None
    }
}
