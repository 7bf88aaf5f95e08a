//! The simulated camera as a [`Camera`]: it renders the frames the world
//! captured as its physics passed each exposure time.

use nalgebra::{Isometry3, Translation3, Unit, UnitQuaternion, Vector3};
use slidetrack_core::{
    Camera, CameraIntrinsics, DeviceError, EncodedImage, ErrorKind, Frame, Image, encode_jpeg,
};

use super::camera::SimCameraRenderer;
use super::rig::SharedWorld;

/// Compresses a rendered image as the camera would deliver it; `None` when
/// it cannot (the frame is then recorded without its image).
pub type FrameEncoder = Box<dyn FnMut(&Image) -> Option<EncodedImage> + Send>;

/// The simulated camera of one trial.
pub struct SimCamera {
    world: SharedWorld,
    renderer: SimCameraRenderer,
    encoder: FrameEncoder,
    object_start_in_hand: Vector3<f64>,
    sliding_axis_in_hand: Unit<Vector3<f64>>,
    intrinsics: CameraIntrinsics,
}

impl SimCamera {
    /// A camera on `world` that renders with `renderer` the object starting
    /// at `object_start_in_hand_m` and sliding along `sliding_axis_in_hand`,
    /// and compresses its frames with the built-in (pure Rust) JPEG encoder.
    /// Starts frame capture at the renderer's frame rate.
    pub fn new(
        world: SharedWorld,
        renderer: SimCameraRenderer,
        object_start_in_hand_m: [f64; 3],
        sliding_axis_in_hand: [f64; 3],
    ) -> Result<SimCamera, DeviceError> {
        let axis = Unit::try_new(Vector3::from(sliding_axis_in_hand), 1e-9).ok_or_else(|| {
            DeviceError::new(ErrorKind::Other, "sim camera", "sliding axis has zero length")
        })?;
        world
            .lock()
            .map_err(|_| DeviceError::new(ErrorKind::Fault, "sim camera", "simulation state poisoned"))?
            .capture_frames(renderer.config().fps);
        let intrinsics = renderer.intrinsics().clone();
        let quality = renderer.config().jpeg_quality;
        let encoder: FrameEncoder = Box::new(move |image| match encode_jpeg(image, quality) {
            Ok(encoded) => Some(encoded),
            Err(e) => {
                tracing::warn!("sim camera: {e}");
                None
            }
        });
        Ok(SimCamera {
            world,
            renderer,
            encoder,
            object_start_in_hand: Vector3::from(object_start_in_hand_m),
            sliding_axis_in_hand: axis,
            intrinsics,
        })
    }

    /// Replaces the JPEG encoder (for example with a faster native one); it
    /// receives every rendered image.
    pub fn with_encoder(mut self, encoder: FrameEncoder) -> SimCamera {
        self.encoder = encoder;
        self
    }

    /// JPEG quality the camera's configuration asks for (1-100).
    pub fn jpeg_quality(&self) -> u8 {
        self.renderer.config().jpeg_quality
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
            let pixels = self.renderer.render_image(&pose, sequence);
            let encoded = (self.encoder)(&pixels);
            Frame { t, sequence, pixels: Some(pixels), encoded }
        }))
    }

    fn intrinsics(&self) -> &CameraIntrinsics {
        &self.intrinsics
    }

    fn device(&self) -> &str {
        "sim camera"
    }
}
