//! Where a trial's marker detections come from: OpenCV's ArUco detector on
//! each camera frame ([`LiveMarkers`]), or the detections a session recorded
//! (the replay rig's `RecordedMarkers`).

use nalgebra::Point3;
use slidetrack_calibration::{MarkerTracker, SlidingProjector, marker_pose};
use slidetrack_control::ObserverError;
use slidetrack_core::{CameraIntrinsics, Frame};
use slidetrack_session::{ArucoDetection, Quaternion};

/// A source of marker detections, one per camera frame.
///
/// # Contract
/// `detect` is called once per frame, in frame order, and returns the
/// detection in that frame: `ArucoDetection::missed()` when the marker was
/// not found (or the frame cannot be searched). An error ends the trial with
/// a safe release.
pub trait MarkerSource: Send {
    /// The detection in `frame`.
    fn detect(&mut self, frame: &Frame) -> Result<ArucoDetection, ObserverError>;
    /// The intrinsics of the camera the detections are in (recorded on
    /// `/camera/calibration`).
    fn intrinsics(&self) -> &CameraIntrinsics;
}

/// OpenCV's detector following the object's marker frame to frame, with its
/// pose and its travel along the sliding axis.
pub struct LiveMarkers {
    /// Finds the object's marker frame to frame.
    pub tracker: MarkerTracker,
    /// Side of the marker's black square (m).
    pub marker_size_m: f64,
    /// The camera's intrinsics.
    pub intrinsics: CameraIntrinsics,
    /// Marker position -> travel along the sliding axis, 0 at the first detection.
    pub projector: SlidingProjector,
}

impl MarkerSource for LiveMarkers {
    fn detect(&mut self, frame: &Frame) -> Result<ArucoDetection, ObserverError> {
        let Some(image) = frame.pixels.as_ref() else { return Ok(ArucoDetection::missed()) };
        let Some(found) = self.tracker.detect(image)? else { return Ok(ArucoDetection::missed()) };
        let mut msg = ArucoDetection {
            detected: true,
            marker_id: Some(found.id),
            corners_px: Some(found.corners_px),
            ..ArucoDetection::missed()
        };
        // A detection whose pose cannot be solved is still a detection (corners),
        // with no position.
        if let Ok(pose) = marker_pose(&found, &self.intrinsics, self.marker_size_m) {
            let t = pose.camera_from_marker.translation.vector;
            let q = pose.camera_from_marker.rotation;
            msg.position_in_camera_m = Some([t.x, t.y, t.z]);
            msg.orientation_in_camera = Some(Quaternion { x: q.i, y: q.j, z: q.k, w: q.w });
            msg.reprojection_error_px = Some(pose.reprojection_error_px);
            msg.position_on_axis_m = self.projector.project(&Point3::from(t));
        }
        Ok(msg)
    }

    fn intrinsics(&self) -> &CameraIntrinsics {
        &self.intrinsics
    }
}
