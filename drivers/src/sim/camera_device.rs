//! The simulated camera as a [`Camera`]: it renders the frames the world
//! captured as its physics passed each exposure time.

use nalgebra::{Isometry3, Translation3, Unit, UnitQuaternion, Vector3};

use super::camera::SimCameraRenderer;
use super::rig::SharedWorld;
use crate::{Camera, CameraIntrinsics, DeviceError, ErrorKind, Frame};

/// The simulated camera of one trial.
pub struct SimCamera {
    world: SharedWorld,
    renderer: SimCameraRenderer,
    object_start_in_hand: Vector3<f64>,
    sliding_axis_in_hand: Unit<Vector3<f64>>,
    intrinsics: CameraIntrinsics,
}

impl SimCamera {
    /// A camera on `world` that renders with `renderer` the object starting
    /// at `object_start_in_hand_m` and sliding along `sliding_axis_in_hand`.
    /// Starts frame capture at the renderer's frame rate.
    pub fn new(
        world: SharedWorld,
        renderer: SimCameraRenderer,
        object_start_in_hand_m: [f64; 3],
        sliding_axis_in_hand: [f64; 3],
    ) -> Result<SimCamera, DeviceError> {
        let axis = Unit::try_new(Vector3::from(sliding_axis_in_hand), 1e-9)
            .ok_or_else(|| DeviceError::new(ErrorKind::Other, "sim camera", "sliding axis has zero length"))?;
        world
            .lock()
            .map_err(|_| DeviceError::new(ErrorKind::Fault, "sim camera", "simulation state poisoned"))?
            .capture_frames(renderer.config().fps);
        let intrinsics = renderer.intrinsics().clone();
        Ok(SimCamera {
            world,
            renderer,
            object_start_in_hand: Vector3::from(object_start_in_hand_m),
            sliding_axis_in_hand: axis,
            intrinsics,
        })
    }

    /// The object's pose in the hand frame after sliding `travel_m` (m).
    pub fn hand_from_object(&self, travel_m: f64) -> Isometry3<f64> {
        let t = self.object_start_in_hand + self.sliding_axis_in_hand.into_inner() * travel_m;
        Isometry3::from_parts(Translation3::from(t), UnitQuaternion::identity())
    }

    /// The camera pose in the hand frame.
    pub fn hand_from_camera(&self) -> Isometry3<f64> {
        *self.renderer.hand_from_camera()
    }
}

impl Camera for SimCamera {
    fn poll(&mut self) -> Result<Option<Frame>, DeviceError> {
        let next = self
            .world
            .lock()
            .map_err(|_| DeviceError::new(ErrorKind::Fault, "sim camera", "simulation state poisoned"))?
            .pop_frame();
        Ok(next.map(|(t, sequence, travel_m)| {
            let pose = self.hand_from_object(travel_m);
            self.renderer.render(&pose, t, sequence)
        }))
    }

    fn intrinsics(&self) -> &CameraIntrinsics {
        &self.intrinsics
    }

    fn device(&self) -> &str {
        "sim camera"
    }
}
