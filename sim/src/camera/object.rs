//! How the object looks: its marker face, the sticker, the marker's bits.

use nalgebra::{Isometry3, Rotation3, Translation3, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};

use super::config::check_range;
use super::error::SimCameraError;

/// How the object looks: its marker face, the sticker and the marker on it.
///
/// The face is a `face_size_m[0]` (wide, along object +y) by `face_size_m[1]`
/// (high, along object +z) rectangle whose outward normal is object +x. The
/// marker's black square (`marker_size_m` per side, border cells included) is
/// printed on a white sticker that extends `sticker_margin_cells` cells beyond
/// it on every side.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ObjectAppearance {
    /// Face width and height (m).
    pub face_size_m: [f64; 2],
    /// Centre of the face in the object frame (m).
    pub face_centre_in_object_m: [f64; 3],
    /// Colour of the face, sRGB 0..255.
    pub face_rgb: [u8; 3],
    /// Side of the marker's black square (m), border cells included.
    pub marker_size_m: f64,
    /// Marker centre on the face, `[right, up]` from the face centre (m).
    pub marker_centre_on_face_m: [f64; 2],
    /// White margin of the sticker around the marker (cells).
    pub sticker_margin_cells: f64,
    /// Colour of the printed black (gray level 0..255).
    pub ink_gray: u8,
    /// Colour of the sticker's white paper (gray level 0..255).
    pub paper_gray: u8,
}

impl Default for ObjectAppearance {
    fn default() -> Self {
        ObjectAppearance {
            face_size_m: [0.06, 0.10],
            face_centre_in_object_m: [0.025, 0.0, 0.0],
            face_rgb: [176, 128, 72],
            marker_size_m: 0.03,
            marker_centre_on_face_m: [0.0, 0.0],
            sticker_margin_cells: 1.0,
            ink_gray: 28,
            paper_gray: 232,
        }
    }
}

impl ObjectAppearance {
    /// Pose of the marker (OpenCV ArUco frame: x right, y up, z out of the
    /// face) in the object frame. The true `camera_from_marker` of a frame is
    /// `hand_from_camera.inverse() * hand_from_object * object_from_marker()`.
    pub fn object_from_marker(&self) -> Isometry3<f64> {
        let [right_m, up_m] = self.marker_centre_on_face_m;
        let centre =
            Vector3::from(self.face_centre_in_object_m) + Vector3::y() * right_m + Vector3::z() * up_m;
        Isometry3::from_parts(Translation3::from(centre), object_from_face_rotation())
    }

    /// Pose of the face (x right, y up, z = outward normal) in the object frame.
    pub fn object_from_face(&self) -> Isometry3<f64> {
        Isometry3::from_parts(
            Translation3::from(Vector3::from(self.face_centre_in_object_m)),
            object_from_face_rotation(),
        )
    }

    /// Side of one marker cell (m).
    pub fn cell_size_m(&self, cells: usize) -> f64 {
        self.marker_size_m / (cells as f64 + 2.0)
    }

    /// Checks every size of the appearance.
    pub fn validate(&self) -> Result<(), SimCameraError> {
        let [w, h] = self.face_size_m;
        check_range("appearance.face_size_m[0]", w, w.is_finite() && w > 0.0, "> 0 m")?;
        check_range("appearance.face_size_m[1]", h, h.is_finite() && h > 0.0, "> 0 m")?;
        let s = self.marker_size_m;
        check_range("appearance.marker_size_m", s, s.is_finite() && s > 0.0, "> 0 m")?;
        let m = self.sticker_margin_cells;
        check_range("appearance.sticker_margin_cells", m, (0.0..=100.0).contains(&m), "0..=100")
    }
}

/// Face axes in the object frame: right = +y, up = +z, normal = +x.
fn object_from_face_rotation() -> UnitQuaternion<f64> {
    let rotation = Rotation3::from_basis_unchecked(&[Vector3::y(), Vector3::z(), Vector3::x()]);
    UnitQuaternion::from_rotation_matrix(&rotation)
}
