//! Sources of segmentation masks and 6D pose measurements. In ROFT's setting
//! (thesis Sec. 5.1) both come from networks that are slow: each result
//! refers to an earlier frame and arrives later. A source is polled once per
//! RGB-D frame and hands over what arrived by that frame's time:
//!
//! - [`SlowNetwork`]: the simulated rig's imitation of such networks, from
//!   the ground truth with noise, outliers, imperfect masks and a delay (5
//!   fps, 200 ms late by default); with [`SlowNetworkConfig::exact`] the
//!   delayed ground truth of the "GT" rows of Table 5.6;
//! - [`TruthSource`]: the ground truth of every frame, without delay (the
//!   label masks of YCB-Video, `vision track --measurements truth`);
//! - [`FileSequence`]: masks and poses listed in CSV files of a directory;
//! - [`SessionMeasurements`]: the `/vision/mask` and `/vision/pose` channels
//!   of a session;
//! - [`ArucoSource`]: poses from an ArUco marker fixed to the object, and
//!   masks rendered from the object's mesh at those poses;
//! - [`ExternalSource`]: masks and poses from a lab's own network, over a
//!   local socket (protocol in `docs/protocols.md`).

mod aruco;
pub mod external;
mod files;
mod network;
mod rendered_mask;
mod source;

pub use aruco::{ArrivalDelay, ArucoConfig, ArucoSource, ArucoStats, PoseConfig};
pub use external::{ExternalConfig, ExternalSource};
pub use files::{FileSequence, SessionMeasurements};
pub use network::{SlowNetwork, SlowNetworkConfig};
pub use rendered_mask::MaskRenderer;
pub use source::{Arrivals, Delayed, FrameTruth, MeasurementSource};

use slidetrack_core::{RgbdFrame, TimeNs};

use crate::VisionError;

/// The ground truth of every frame, immediately: masks, poses, or both.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TruthSource {
    /// Deliver the true mask.
    pub masks: bool,
    /// Deliver the true pose.
    pub poses: bool,
}

impl MeasurementSource for TruthSource {
    fn on_frame(&mut self, t: TimeNs, truth: Option<FrameTruth<'_>>) -> Result<Arrivals, VisionError> {
        let mut out = Arrivals::default();
        if let Some(truth) = truth {
            if self.masks {
                out.masks.push(Delayed { frame_t: t, arrival_t: t, value: truth.mask.clone() });
            }
            if self.poses {
                out.poses.push(Delayed { frame_t: t, arrival_t: t, value: *truth.camera_from_object });
            }
        }
        Ok(out)
    }
}

/// Masks from one source and poses from another.
pub struct Combined {
    /// Where the masks come from.
    pub masks: Box<dyn MeasurementSource>,
    /// Where the poses come from.
    pub poses: Box<dyn MeasurementSource>,
}

impl MeasurementSource for Combined {
    fn on_frame(&mut self, t: TimeNs, truth: Option<FrameTruth<'_>>) -> Result<Arrivals, VisionError> {
        let masks = self.masks.on_frame(t, truth)?.masks;
        let poses = self.poses.on_frame(t, truth)?.poses;
        Ok(Arrivals { masks, poses })
    }

    fn on_rgbd_frame(
        &mut self,
        frame: &RgbdFrame,
        truth: Option<FrameTruth<'_>>,
    ) -> Result<Arrivals, VisionError> {
        let masks = self.masks.on_rgbd_frame(frame, truth)?.masks;
        let poses = self.poses.on_rgbd_frame(frame, truth)?.poses;
        Ok(Arrivals { masks, poses })
    }
}

#[cfg(test)]
mod tests {
    use nalgebra::Isometry3;
    use slidetrack_estimators::roft::Mask;

    use super::*;

    #[test]
    fn truth_delivers_every_frame_at_once() {
        let mut s = TruthSource { masks: true, poses: false };
        let mask = Mask::empty(4, 4);
        let pose = Isometry3::identity();
        let a = s.on_frame(TimeNs(7), Some(FrameTruth { camera_from_object: &pose, mask: &mask })).unwrap();
        assert_eq!(a.masks.len(), 1);
        assert_eq!(a.masks[0].frame_t, TimeNs(7));
        assert!(a.poses.is_empty());
        assert_eq!(s.on_frame(TimeNs(8), None).unwrap(), Arrivals::default());
    }
}
