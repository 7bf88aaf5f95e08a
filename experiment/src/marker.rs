//! Where a trial's marker detections come from: OpenCV's ArUco detector on
//! each camera frame ([`LiveMarkers`], or [`LiveBoard`] for a board), or the detections a session recorded
//! (the replay rig's `RecordedMarkers`).

use nalgebra::Point3;
use slidetrack_calibration::{
    Board, MarkerDetector, MarkerTracker, SlidingProjector, board_pose, marker_pose,
};
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

/// OpenCV's detector finding a board's markers in every frame, with the
/// board's pose from all of them (a GridBoard's marker corners, a ChArUco
/// board's interpolated corners) and its travel along the sliding axis.
///
/// The message describes the board's centre frame
/// ([`slidetrack_core::BoardLayout::board_from_centre`]: x right, y up, z out
/// of the print, like a single marker's frame): its position and
/// orientation, the RMS reprojection error of all the points used, and as
/// `corners_px` the board's outer corners (top-left, top-right,
/// bottom-right, bottom-left as printed) projected through the pose;
/// `marker_id` is the lowest id seen. The whole frame is searched each time
/// (a board covers much of it).
pub struct LiveBoard {
    /// Finds the board's markers.
    pub detector: MarkerDetector,
    /// The board.
    pub board: Board,
    /// The camera's intrinsics.
    pub intrinsics: CameraIntrinsics,
    /// Board centre position -> travel along the sliding axis, 0 at the first detection.
    pub projector: SlidingProjector,
}

impl MarkerSource for LiveBoard {
    fn detect(&mut self, frame: &Frame) -> Result<ArucoDetection, ObserverError> {
        let Some(image) = frame.pixels.as_ref() else { return Ok(ArucoDetection::missed()) };
        let found = self.detector.detect(image)?;
        let obs = self.board.observe_image(&found, image, &self.intrinsics)?;
        if obs.markers == 0 {
            return Ok(ArucoDetection::missed());
        }
        let mut msg = ArucoDetection {
            detected: true,
            marker_id: obs.ids.iter().min().copied(),
            ..ArucoDetection::missed()
        };
        // Too few points for a pose: detected, with no position.
        let Ok(pose) = board_pose(&obs, &self.intrinsics) else { return Ok(msg) };
        let layout = self.board.layout();
        let centre = pose.camera_from_centre(layout);
        let t = centre.translation.vector;
        let q = centre.rotation;
        let [w, h] = layout.size_m();
        let outline = [[0.0, 0.0], [w, 0.0], [w, h], [0.0, h]].map(|[x, y]| {
            let p = pose.camera_from_board * Point3::new(x, y, 0.0);
            self.intrinsics.project([p.x, p.y, p.z]).map(|(u, v)| [u, v])
        });
        if let [Some(a), Some(b), Some(c), Some(d)] = outline {
            msg.corners_px = Some([a, b, c, d]);
        }
        msg.position_in_camera_m = Some([t.x, t.y, t.z]);
        msg.orientation_in_camera = Some(Quaternion { x: q.i, y: q.j, z: q.k, w: q.w });
        msg.reprojection_error_px = Some(pose.reprojection_error_px);
        msg.position_on_axis_m = self.projector.project(&Point3::from(t));
        Ok(msg)
    }

    fn intrinsics(&self) -> &CameraIntrinsics {
        &self.intrinsics
    }
}
