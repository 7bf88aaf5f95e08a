//! The hand frame for labelling (`label --hand-calibration FILE`): the
//! camera's pose in the hand from a hand calibration (what `calibrate hand
//! --out` writes), and the sliding axis and contact frame of a parallel
//! gripper from the hand's geometry (`[hand_geometry]`).
//!
//! The hand frame is the rig's: x out of the palm, y to the hand's left,
//! z up. A parallel gripper's geometry is two directions and a point:
//! - `finger_axis_in_hand` `f`: from the palm towards the fingertips;
//! - `closing_axis_in_hand` `c`: the direction the pads close along, the
//!   normal of the pads' faces (from the right pad towards the left one);
//! - `grip_point_in_hand_m`: midway between the pads' centres.
//!
//! The pads' faces lie in the plane normal to `c`. An object held between
//! them can move in that plane only; along the fingers (`f`, made
//! perpendicular to `c`) the palm stops it and the fingertips let it go, so
//! it slides through the grip along the other direction of the plane:
//! **sliding axis `s = c x f`** (unit). With the defaults (`f = +x`,
//! `c = +y`) `s = -z`: down, as the rig's `[geometry]` default and the
//! thesis's rig, where the object slides out of the grip under its weight.
//! The **contact frame** of the gripper has its normal along `c`, its x axis
//! along `s` and its origin at the grip point.

use std::path::{Path, PathBuf};

use nalgebra::{Isometry3, Point3, Unit, Vector3};
use serde::{Deserialize, Serialize};
use slidetrack_core::CameraPlacement;
use thiserror::Error;

use crate::axis::SlidingAxis;
use crate::in_hand::{ContactFrame, ContactSource, InHandOptions};

/// The least angle between the finger and the closing axes (degrees): below
/// it the pads' plane has no defined in-plane direction across the fingers.
pub const MIN_AXES_ANGLE_DEG: f64 = 30.0;

/// Why a hand calibration or a hand geometry cannot be used.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum HandFrameError {
    /// The calibration file cannot be read.
    #[error("cannot read the hand calibration {path}: {source}")]
    Read {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// The calibration file is not a `[camera] placement` TOML.
    #[error("hand calibration {path}: {detail}")]
    Parse {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        detail: String,
    },
    /// The geometry's axes are unusable.
    #[error("[hand_geometry] ({from}): {detail}")]
    Geometry {
        /// Where the geometry came from.
        from: String,
        /// What is wrong.
        detail: String,
    },
}

/// A parallel gripper's geometry in the hand frame (`[hand_geometry]`; see
/// the module documentation). Defaults: fingers along `+x`, closing along
/// `+y`, grip point at the rig's default grasp point `(0.10, 0, 0)` m.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct HandGeometry {
    /// From the palm towards the fingertips (hand frame, any length).
    pub finger_axis_in_hand: [f64; 3],
    /// The pads' closing direction, normal to their faces (hand frame, any length).
    pub closing_axis_in_hand: [f64; 3],
    /// Midway between the pads' centres (m, hand frame).
    pub grip_point_in_hand_m: [f64; 3],
}

impl Default for HandGeometry {
    fn default() -> Self {
        HandGeometry {
            finger_axis_in_hand: [1.0, 0.0, 0.0],
            closing_axis_in_hand: [0.0, 1.0, 0.0],
            grip_point_in_hand_m: [0.10, 0.0, 0.0],
        }
    }
}

/// The geometry's unit axes: closing `c`, fingers `f` (perpendicular to
/// `c`) and sliding `s = c x f`, in the hand frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GripperAxes {
    /// The closing axis (pad normal).
    pub closing: Unit<Vector3<f64>>,
    /// The finger axis, made perpendicular to the closing axis.
    pub fingers: Unit<Vector3<f64>>,
    /// The sliding axis, `closing x fingers`.
    pub sliding: Unit<Vector3<f64>>,
}

impl HandGeometry {
    /// The unit axes; `from` names where the geometry came from, for the error.
    pub fn axes(&self, from: &str) -> Result<GripperAxes, HandFrameError> {
        let bad = |detail: String| HandFrameError::Geometry { from: from.to_string(), detail };
        let unit = |v: [f64; 3], name: &str| {
            Unit::try_new(Vector3::from(v), 1e-9)
                .filter(|u| u.iter().all(|x| x.is_finite()))
                .ok_or_else(|| bad(format!("{name} {v:?} has zero or non-finite length")))
        };
        let closing = unit(self.closing_axis_in_hand, "closing_axis_in_hand")?;
        let f = unit(self.finger_axis_in_hand, "finger_axis_in_hand")?;
        let angle_deg = f.dot(&closing).clamp(-1.0, 1.0).acos().to_degrees();
        if !(MIN_AXES_ANGLE_DEG..=180.0 - MIN_AXES_ANGLE_DEG).contains(&angle_deg) {
            return Err(bad(format!(
                "finger_axis_in_hand {:?} and closing_axis_in_hand {:?} are {angle_deg:.1} deg apart \
                 (at least {MIN_AXES_ANGLE_DEG} from parallel needed)",
                self.finger_axis_in_hand, self.closing_axis_in_hand
            )));
        }
        let fingers = Unit::new_normalize(f.into_inner() - closing.into_inner() * closing.dot(&f));
        let sliding = Unit::new_normalize(closing.cross(&fingers));
        if !self.grip_point_in_hand_m.iter().all(|v| v.is_finite()) {
            return Err(bad(format!("grip_point_in_hand_m {:?} is not finite", self.grip_point_in_hand_m)));
        }
        Ok(GripperAxes { closing, fingers, sliding })
    }

    /// The gripper's contact frame: normal along the closing axis, x along
    /// the sliding axis, origin at the grip point.
    pub fn contact_frame(&self, from: &str) -> Result<ContactFrame, HandFrameError> {
        let a = self.axes(from)?;
        let how = format!(
            "from the hand geometry ({from}): normal = the closing axis, x = the sliding axis (closing x fingers), \
             origin = the grip point"
        );
        ContactFrame::new(
            a.closing.into_inner(),
            a.sliding.into_inner(),
            Vector3::from(self.grip_point_in_hand_m),
            how,
        )
        .ok_or_else(|| HandFrameError::Geometry { from: from.to_string(), detail: "no contact frame".into() })
    }
}

/// A hand calibration file: `[camera] placement` (as `calibrate hand --out`
/// writes it) and, optionally, the hand's `[hand_geometry]`. Other tables are
/// ignored, so a rig configuration is also one.
#[derive(Clone, Debug, PartialEq)]
pub struct HandCalibrationFile {
    /// The file.
    pub path: PathBuf,
    /// The camera's pose in the hand frame.
    pub hand_from_camera: Isometry3<f64>,
    /// The hand's geometry, when the file has one.
    pub geometry: Option<HandGeometry>,
}

#[derive(Deserialize)]
struct CalibrationToml {
    camera: Option<CameraTable>,
    hand_geometry: Option<HandGeometry>,
}

#[derive(Deserialize)]
struct CameraTable {
    placement: Option<CameraPlacement>,
}

/// The `[hand_geometry]` of a rig configuration (TOML), if it has one.
#[derive(Deserialize)]
struct RigHandGeometry {
    hand_geometry: Option<HandGeometry>,
}

impl HandCalibrationFile {
    /// Reads and checks the file at `path`.
    pub fn load(path: &Path) -> Result<HandCalibrationFile, HandFrameError> {
        let text = std::fs::read_to_string(path)
            .map_err(|source| HandFrameError::Read { path: path.to_path_buf(), source })?;
        Self::parse(&text, path)
    }

    /// Parses `text`, the contents of `path`.
    pub fn parse(text: &str, path: &Path) -> Result<HandCalibrationFile, HandFrameError> {
        let parse = |detail: String| HandFrameError::Parse { path: path.to_path_buf(), detail };
        let file: CalibrationToml = toml::from_str(text).map_err(|e| parse(e.message().to_string()))?;
        let placement = file.camera.and_then(|c| c.placement).ok_or_else(|| {
            parse("no [camera] placement (write one with `slidetrack calibrate hand --out FILE`)".into())
        })?;
        let hand_from_camera =
            placement.hand_from_camera().map_err(|e| parse(format!("[camera] placement: {e}")))?;
        let file =
            HandCalibrationFile { path: path.to_path_buf(), hand_from_camera, geometry: file.hand_geometry };
        if let Some(g) = &file.geometry {
            g.axes(&path.display().to_string())?;
        }
        Ok(file)
    }

    /// The hand frame of a session recorded with `rig_config` (TOML): the
    /// geometry of this file, else of the session's rig configuration, else
    /// the defaults.
    pub fn hand_frame(&self, rig_config: Option<&str>) -> Result<HandFrame, HandFrameError> {
        let from_rig =
            rig_config.and_then(|t| toml::from_str::<RigHandGeometry>(t).ok()).and_then(|r| r.hand_geometry);
        let (geometry, geometry_from) = match (&self.geometry, from_rig) {
            (Some(g), _) => (g.clone(), format!("[hand_geometry] of {}", self.path.display())),
            (None, Some(g)) => (g, "[hand_geometry] of the session's rig_config".to_string()),
            (None, None) => (HandGeometry::default(), "the default [hand_geometry]".to_string()),
        };
        let axes = geometry.axes(&geometry_from)?;
        let contact = geometry.contact_frame(&geometry_from)?;
        Ok(HandFrame {
            calibration: self.path.clone(),
            hand_from_camera: self.hand_from_camera,
            geometry,
            geometry_from,
            axes,
            contact,
        })
    }
}

/// The hand frame of one session: the calibration and the geometry it uses.
#[derive(Clone, Debug, PartialEq)]
pub struct HandFrame {
    /// The calibration file.
    pub calibration: PathBuf,
    /// The camera's pose in the hand frame (from the calibration).
    pub hand_from_camera: Isometry3<f64>,
    /// The geometry used.
    pub geometry: HandGeometry,
    /// Where the geometry came from, in words.
    pub geometry_from: String,
    /// The geometry's axes.
    pub axes: GripperAxes,
    /// The gripper's contact frame.
    pub contact: ContactFrame,
}

impl HandFrame {
    /// The sliding axis seen from the calibrated camera.
    pub fn sliding_axis(&self) -> SlidingAxis {
        SlidingAxis { hand_from_camera: self.hand_from_camera, axis_in_hand: self.axes.sliding }
    }

    /// The in-hand labelling's `options` with the calibrated camera pose and
    /// the geometry's contact frame (neither estimated nor taken from the rig
    /// configuration).
    pub fn in_hand_options(&self, options: &InHandOptions) -> InHandOptions {
        InHandOptions {
            hand_from_camera: Some(self.hand_from_camera),
            contact: ContactSource::Given(self.contact.clone()),
            ..options.clone()
        }
    }

    /// A point of the camera frame in the hand frame (m).
    pub fn in_hand(&self, point_in_camera: &Point3<f64>) -> Point3<f64> {
        self.hand_from_camera * point_in_camera
    }

    /// Where the sliding axis came from, in words (for the labelling's record).
    pub fn axis_source(&self) -> String {
        let s = self.axes.sliding;
        format!(
            "position_in_camera_m of /aruco/detections moved into the hand frame with the hand calibration {} and \
             projected on the sliding axis of the hand geometry, closing x fingers = ({:.6}, {:.6}, {:.6}) in the \
             hand frame ({})",
            self.calibration.display(),
            s.x,
            s.y,
            s.z,
            self.geometry_from
        )
    }
}

#[cfg(test)]
#[path = "hand_frame_tests.rs"]
mod tests;
