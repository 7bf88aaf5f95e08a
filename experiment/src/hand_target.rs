//! The marker fixed to the hand for `calibrate hand` (`[hand_target]` in the rig TOML).

use anyhow::Result;
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};

/// The marker fixed to the hand for `calibrate hand` (`[hand_target]`).
///
/// TOML: `[hand_target]` with `dictionary`, `id`, `marker_size_m` and
/// `hand_from_target = { translation_m = [...], quaternion_xyzw = [...] }`:
/// the marker frame (OpenCV ArUco: origin at its centre, x right, y up as
/// printed, z out of the print) in the hand frame, from the hand's geometry
/// (e.g. the CAD of the plate screwed to the palm).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HandTargetConfig {
    /// OpenCV predefined dictionary name.
    #[serde(default = "default_dictionary")]
    pub dictionary: String,
    /// Marker id.
    pub id: u32,
    /// Side of the marker's black square (m), border cells included.
    pub marker_size_m: f64,
    /// The marker frame in the hand frame.
    pub hand_from_target: MountPose,
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
