//! The marker or board fixed to the hand for `calibrate hand` (`[hand_target]`
//! in the rig TOML), and finding it in an image.

use anyhow::{Context, Result};
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};
use slidetrack_calibration::hand_eye::TargetView;
use slidetrack_calibration::{Board, Dictionary, MarkerDetector, MarkerTracker, board_pose, marker_pose};
use slidetrack_core::{BoardLayout, CameraIntrinsics, Image};

/// The marker (or board) fixed to the hand for `calibrate hand` (`[hand_target]`).
///
/// TOML: `[hand_target]` with `dictionary`, `id`, `marker_size_m` and
/// `hand_from_target = { translation_m = [...], quaternion_xyzw = [...] }`:
/// the marker frame (OpenCV ArUco: origin at its centre, x right, y up as
/// printed, z out of the print) in the hand frame, from the hand's geometry
/// (e.g. the CAD of the plate screwed to the palm). With `[hand_target.board]`
/// (a GridBoard or ChArUco layout, as `[marker.board]`) the target is that
/// board instead, `id` and `marker_size_m` are not used, and
/// `hand_from_target` is the board's centre frame (x right, y up, z out of
/// the print, like a single marker's).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HandTargetConfig {
    /// OpenCV predefined dictionary name.
    #[serde(default = "default_dictionary")]
    pub dictionary: String,
    /// Marker id (the single marker).
    #[serde(default)]
    pub id: u32,
    /// Side of the single marker's black square (m), border cells included.
    #[serde(default)]
    pub marker_size_m: f64,
    /// A board instead of the single marker.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub board: Option<BoardLayout>,
    /// The marker's (or the board centre's) frame in the hand frame.
    pub hand_from_target: MountPose,
}

impl HandTargetConfig {
    /// The target in words, for messages.
    pub fn describe(&self) -> String {
        match &self.board {
            None => format!("marker {} of {}", self.id, self.dictionary),
            Some(BoardLayout::Grid { .. }) => format!("the GridBoard of {}", self.dictionary),
            Some(BoardLayout::Charuco { .. }) => format!("the ChArUco board of {}", self.dictionary),
        }
    }
}

/// Finds the hand's target in images and measures its pose.
pub enum TargetFinder {
    /// The single marker.
    Marker {
        /// Follows the marker's id.
        tracker: MarkerTracker,
        /// Its side (m).
        size_m: f64,
    },
    /// A board: every marker of it, its pose from all their points.
    Board {
        /// Finds the markers.
        detector: MarkerDetector,
        /// The board.
        board: Board,
    },
}

impl TargetFinder {
    /// The finder of `target`; fails on an unknown dictionary, a bad
    /// board layout or a single marker of no size.
    pub fn new(target: &HandTargetConfig) -> Result<TargetFinder> {
        let dictionary = Dictionary::from_name(&target.dictionary)?;
        match &target.board {
            None => {
                anyhow::ensure!(
                    target.marker_size_m.is_finite() && target.marker_size_m > 0.0,
                    "hand_target.marker_size_m must be a positive size (m), got {}",
                    target.marker_size_m
                );
                Ok(TargetFinder::Marker {
                    tracker: MarkerTracker::new(dictionary, target.id)?,
                    size_m: target.marker_size_m,
                })
            }
            Some(layout) => Ok(TargetFinder::Board {
                board: Board::new(layout.clone(), &dictionary).context("hand_target.board")?,
                detector: MarkerDetector::new(dictionary)?,
            }),
        }
    }

    /// The target's pose in `image`, `None` when it is not found (or a
    /// board shows too few points for a pose).
    pub fn view(&mut self, image: &Image, intrinsics: &CameraIntrinsics) -> Result<Option<TargetView>> {
        match self {
            TargetFinder::Marker { tracker, size_m } => {
                tracker.reset();
                let Some(d) = tracker.detect(image)? else { return Ok(None) };
                let p = marker_pose(&d, intrinsics, *size_m)?;
                Ok(Some(TargetView {
                    camera_from_target: p.camera_from_marker,
                    reprojection_error_px: p.reprojection_error_px,
                }))
            }
            TargetFinder::Board { detector, board } => {
                let found = detector.detect(image)?;
                let obs = board.observe_image(&found, image, intrinsics)?;
                if obs.markers == 0 {
                    return Ok(None);
                }
                let Ok(pose) = board_pose(&obs, intrinsics) else { return Ok(None) };
                Ok(Some(TargetView {
                    camera_from_target: pose.camera_from_centre(board.layout()),
                    reprojection_error_px: pose.reprojection_error_px,
                }))
            }
        }
    }
}

fn default_dictionary() -> String {
    "DICT_6X6_250".into()
}

/// A rigid pose: translation (m) and rotation `[x, y, z, w]`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MountPose {
    /// Translation (m).
    pub translation_m: [f64; 3],
    /// Rotation as a quaternion `[x, y, z, w]` (normalised on use).
    pub quaternion_xyzw: [f64; 4],
}

impl MountPose {
    /// The pose as an isometry; fails on a quaternion of no usable norm.
    pub fn isometry(&self) -> Result<Isometry3<f64>> {
        let [x, y, z, w] = self.quaternion_xyzw;
        let q = nalgebra::Quaternion::new(w, x, y, z);
        let n = q.norm();
        anyhow::ensure!(
            n.is_finite() && n > 1e-9,
            "hand_target.hand_from_target.quaternion_xyzw {:?} has no usable norm",
            self.quaternion_xyzw
        );
        Ok(Isometry3::from_parts(
            Translation3::from(Vector3::from(self.translation_m)),
            UnitQuaternion::from_quaternion(q),
        ))
    }
}
