//! [`InHandRgbd`]: the in-hand sliding scene seen by an RGB-D camera placed
//! like the rig's camera, so that the vision trackers can run beside the
//! dEKF on the same trial. The object is the box of its geometry; the
//! fingers are not drawn (they would only occlude it).

use nalgebra::{Isometry3, Vector3};
use slidetrack_core::{CameraIntrinsics, ObjectTruth, RgbdFrame, TimeNs};
use slidetrack_render::TriangleMesh;

use super::error::RgbdSimError;
use super::scene::{RgbdScene, RgbdSceneConfig};
use super::texture::Texture;
use crate::ObjectGeometry;
use crate::camera::SimCameraConfig;

/// The in-hand scene's RGB-D rendering.
pub struct InHandRgbd {
    scene: RgbdScene,
    hand_from_camera: Isometry3<f64>,
}

impl InHandRgbd {
    /// An RGB-D camera with the pose and the pinhole intrinsics of `camera`
    /// (its distortion is dropped: RGB-D images come rectified), looking at
    /// a box of `geometry` (x towards the camera: `depth_m`, y: `width_m`,
    /// z along the sliding axis: `length_m`), with the wall 0.6 m behind the
    /// hand.
    pub fn new(
        camera: &SimCameraConfig,
        geometry: &ObjectGeometry,
        seed: u64,
    ) -> Result<InHandRgbd, RgbdSimError> {
        let hand_from_camera = camera.hand_from_camera()?;
        let mut intrinsics = camera.intrinsics.clone();
        intrinsics.distortion = [0.0; 5];
        let wall_depth_m = hand_from_camera.translation.vector.norm() + 0.6;
        let config = RgbdSceneConfig { intrinsics, wall_depth_m, ..RgbdSceneConfig::vga(seed) };
        let mesh = TriangleMesh::cuboid([geometry.depth_m, geometry.width_m, geometry.length_m]);
        let texture = Texture::packaging(seed ^ 0x696e_6861_6e64, [0.7, 0.5, 0.3], [0.95, 0.9, 0.8], 0.1);
        Ok(InHandRgbd { scene: RgbdScene::new(config, mesh, texture)?, hand_from_camera })
    }

    /// The camera pose in the hand frame.
    pub fn hand_from_camera(&self) -> &Isometry3<f64> {
        &self.hand_from_camera
    }

    /// The RGB-D camera's intrinsics (the rig camera's, without distortion).
    pub fn intrinsics(&self) -> &CameraIntrinsics {
        &self.scene.config().intrinsics
    }

    /// The object's mesh.
    pub fn mesh(&self) -> &TriangleMesh {
        self.scene.mesh()
    }

    /// Renders the frame at `t` with the object at `hand_from_object`, moving
    /// at `velocity_in_hand_mps` without rotating: the frame, the ground-truth
    /// mask and the truth in the camera frame.
    pub fn render(
        &self,
        hand_from_object: &Isometry3<f64>,
        velocity_in_hand_mps: Vector3<f64>,
        t: TimeNs,
        sequence: u64,
    ) -> (RgbdFrame, Vec<u8>, ObjectTruth) {
        let camera_from_object = self.hand_from_camera.inverse() * hand_from_object;
        let r = self.scene.render(&camera_from_object, sequence);
        let truth = ObjectTruth {
            t,
            camera_from_object,
            linear_velocity_mps: self.hand_from_camera.rotation.inverse() * velocity_in_hand_mps,
            angular_velocity_radps: Vector3::zeros(),
        };
        let frame = RgbdFrame {
            t,
            sequence,
            color: r.color,
            depth: r.depth,
            intrinsics: self.scene.config().intrinsics.clone(),
        };
        (frame, r.mask, truth)
    }
}
