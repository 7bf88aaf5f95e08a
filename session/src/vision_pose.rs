//! The RGB-D and vision-tracking channels: colour, depth and masks of RGB-D
//! cameras, the delayed masks and poses of a segmentation / pose-estimation
//! source, the simulator's object truth, and the trackers' estimates.
//!
//! Images and poses use Foxglove's published schemas (`foxglove.RawImage`,
//! `foxglove.CompressedImage`, `foxglove.CameraCalibration`,
//! `foxglove.PoseInFrame`, `foxglove.FrameTransform`), so Foxglove shows them
//! (the 3D panel places the tracked object with the transforms).

use base64::Engine as _;
use base64::engine::general_purpose::STANDARD as BASE64;
use nalgebra::{Isometry3, Quaternion as NaQuaternion, Translation3, UnitQuaternion, Vector3};
use serde::{Deserialize, Deserializer, Serialize, Serializer};
use serde_json::Value;
use slidetrack_core::{DepthImage, ObjectTruth as SimObjectTruth, TimeNs};

use super::channel::{ChannelMessage, ChannelSpec, channel};
use super::schema::{Foxglove, derived};
use super::vision::{CameraCalibration, CompressedImage, FoxgloveTime, Quaternion};

fn to_base64<S: Serializer>(bytes: &[u8], s: S) -> Result<S::Ok, S::Error> {
    s.serialize_str(&BASE64.encode(bytes))
}

fn from_base64<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<u8>, D::Error> {
    let s = <std::borrow::Cow<'de, str>>::deserialize(d)?;
    BASE64.decode(s.as_bytes()).map_err(serde::de::Error::custom)
}

/// An uncompressed image (`foxglove.RawImage`).
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct RawImage {
    /// Time of the frame the image belongs to, session clock.
    pub timestamp: FoxgloveTime,
    /// The camera's optical frame.
    pub frame_id: String,
    /// Width (px).
    pub width: u32,
    /// Height (px).
    pub height: u32,
    /// `16UC1` (depth, millimetres, little-endian) or `mono8` (masks).
    pub encoding: String,
    /// Bytes per row.
    pub step: u32,
    /// The pixels (base64 in JSON).
    #[serde(serialize_with = "to_base64", deserialize_with = "from_base64")]
    pub data: Vec<u8>,
}

impl RawImage {
    /// A depth image as `16UC1` in millimetres.
    pub fn depth(t: TimeNs, frame_id: &str, depth: &DepthImage) -> RawImage {
        let mm = depth.to_millimetres();
        RawImage {
            timestamp: t.into(),
            frame_id: frame_id.into(),
            width: mm.width,
            height: mm.height,
            encoding: "16UC1".into(),
            step: mm.width * 2,
            data: mm.data.iter().flat_map(|d| d.to_le_bytes()).collect(),
        }
    }

    /// A mask as `mono8` (255 inside, 0 outside).
    pub fn mask(t: TimeNs, frame_id: &str, width: u32, height: u32, inside: &[u8]) -> RawImage {
        RawImage {
            timestamp: t.into(),
            frame_id: frame_id.into(),
            width,
            height,
            encoding: "mono8".into(),
            step: width,
            data: inside.iter().map(|v| if *v != 0 { 255 } else { 0 }).collect(),
        }
    }

    /// The depth back, `None` unless `16UC1` with the right size.
    pub fn to_depth(&self) -> Option<DepthImage> {
        let n = self.width as usize * self.height as usize;
        if self.encoding != "16UC1" || self.step != self.width * 2 || self.data.len() != 2 * n {
            return None;
        }
        let data = self.data.chunks_exact(2).map(|b| u16::from_le_bytes([b[0], b[1]])).collect();
        Some(DepthImage { width: self.width, height: self.height, data, scale_m: 0.001 })
    }

    /// The mask back (non-zero inside), `None` unless `mono8` with the right size.
    pub fn to_mask(&self) -> Option<Vec<u8>> {
        let n = self.width as usize * self.height as usize;
        (self.encoding == "mono8" && self.step == self.width && self.data.len() == n)
            .then(|| self.data.clone())
    }
}

/// A pose in a frame (`foxglove.PoseInFrame`).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct PoseInFrame {
    /// Time the pose refers to, session clock.
    pub timestamp: FoxgloveTime,
    /// The frame the pose is expressed in (`camera`).
    pub frame_id: String,
    /// The pose.
    pub pose: Pose,
}

/// `foxglove.Pose`: position (m) and orientation.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Pose {
    /// Position (m).
    pub position: XyzM,
    /// Orientation.
    pub orientation: Quaternion,
}

/// `foxglove.Vector3`: `{x, y, z}`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct XyzM {
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
    /// z.
    pub z: f64,
}

impl From<Vector3<f64>> for XyzM {
    fn from(v: Vector3<f64>) -> XyzM {
        XyzM { x: v.x, y: v.y, z: v.z }
    }
}

impl From<&UnitQuaternion<f64>> for Quaternion {
    fn from(q: &UnitQuaternion<f64>) -> Quaternion {
        Quaternion { x: q.i, y: q.j, z: q.k, w: q.w }
    }
}

impl Pose {
    /// The pose of an isometry.
    pub fn from_isometry(p: &Isometry3<f64>) -> Pose {
        Pose { position: p.translation.vector.into(), orientation: (&p.rotation).into() }
    }

    /// The isometry back; `None` for a non-finite pose or a zero quaternion.
    pub fn to_isometry(&self) -> Option<Isometry3<f64>> {
        let o = &self.orientation;
        let q = NaQuaternion::new(o.w, o.x, o.y, o.z);
        let norm = q.norm();
        let p = &self.position;
        let finite = [p.x, p.y, p.z, o.x, o.y, o.z, o.w].iter().all(|v| v.is_finite());
        (finite && norm > 1e-9).then(|| {
            Isometry3::from_parts(Translation3::new(p.x, p.y, p.z), UnitQuaternion::new_normalize(q))
        })
    }
}

impl PoseInFrame {
    /// `camera_from_object` at `t` in frame `frame_id`.
    pub fn new(t: TimeNs, frame_id: &str, camera_from_object: &Isometry3<f64>) -> PoseInFrame {
        PoseInFrame {
            timestamp: t.into(),
            frame_id: frame_id.into(),
            pose: Pose::from_isometry(camera_from_object),
        }
    }
}

/// A transform between two frames (`foxglove.FrameTransform`).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct FrameTransform {
    /// Time of the transform, session clock.
    pub timestamp: FoxgloveTime,
    /// The parent frame (`camera`).
    pub parent_frame_id: String,
    /// The child frame (`object/<tracker>`).
    pub child_frame_id: String,
    /// Translation of the child's origin in the parent frame (m).
    pub translation: XyzM,
    /// Rotation of the child frame in the parent frame.
    pub rotation: Quaternion,
}

impl FrameTransform {
    /// `parent_from_child` at `t`.
    pub fn new(t: TimeNs, parent: &str, child: &str, parent_from_child: &Isometry3<f64>) -> FrameTransform {
        FrameTransform {
            timestamp: t.into(),
            parent_frame_id: parent.into(),
            child_frame_id: child.into(),
            translation: parent_from_child.translation.vector.into(),
            rotation: (&parent_from_child.rotation).into(),
        }
    }
}

/// The velocity estimated by a tracker: mixed velocity `(ṗ, ω)` of the
/// object in the camera frame.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct VelocityEstimate {
    /// The frame the velocities are expressed in (`camera`).
    pub frame_id: String,
    /// Velocity of the object frame's origin (m/s).
    pub linear_velocity_mps: [f64; 3],
    /// Angular velocity (rad/s).
    pub angular_velocity_radps: [f64; 3],
}

/// `/sim/object`: the simulator's truth about the object seen by the RGB-D camera.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct ObjectTruth {
    /// Position of the object frame in the camera frame (m).
    pub position_m: [f64; 3],
    /// Orientation of the object frame in the camera frame (`camera_from_object`).
    pub orientation: Quaternion,
    /// Velocity of the object origin in the camera frame (m/s).
    pub linear_velocity_mps: [f64; 3],
    /// Angular velocity in the camera frame (rad/s).
    pub angular_velocity_radps: [f64; 3],
}

impl From<&SimObjectTruth> for ObjectTruth {
    fn from(t: &SimObjectTruth) -> ObjectTruth {
        let p = t.camera_from_object.translation.vector;
        ObjectTruth {
            position_m: [p.x, p.y, p.z],
            orientation: (&t.camera_from_object.rotation).into(),
            linear_velocity_mps: t.linear_velocity_mps.into(),
            angular_velocity_radps: t.angular_velocity_radps.into(),
        }
    }
}

impl ObjectTruth {
    /// The truth at `t` back, `None` if a number is not finite.
    pub fn to_sim(&self, t: TimeNs) -> Option<SimObjectTruth> {
        let [x, y, z] = self.position_m;
        let pose = Pose { position: XyzM { x, y, z }, orientation: self.orientation }.to_isometry()?;
        let v = Vector3::from(self.linear_velocity_mps);
        let w = Vector3::from(self.angular_velocity_radps);
        (v.iter().chain(w.iter()).all(|c| c.is_finite())).then_some(SimObjectTruth {
            t,
            camera_from_object: pose,
            linear_velocity_mps: v,
            angular_velocity_radps: w,
        })
    }
}

impl ChannelMessage for ObjectTruth {
    const TOPIC: &'static str = "/sim/object";
    const SCHEMA_NAME: &'static str = "slidetrack.ObjectTruth";
    fn json_schema() -> Value {
        derived::<Self>(Self::SCHEMA_NAME)
    }
}

channel!(
    /// `/rgbd/color`: colour frames of the RGB-D camera (JPEG).
    RgbdColor(CompressedImage), "/rgbd/color", "foxglove.CompressedImage", Foxglove::CompressedImage.schema()
);
channel!(
    /// `/rgbd/calibration`: the RGB-D camera's intrinsics (no distortion).
    RgbdCalibration(CameraCalibration), "/rgbd/calibration", "foxglove.CameraCalibration",
    Foxglove::CameraCalibration.schema()
);
channel!(
    /// `/rgbd/mask`: the simulator's ground-truth segmentation, `mono8`.
    RgbdMask(RawImage), "/rgbd/mask", "foxglove.RawImage", Foxglove::RawImage.schema()
);
channel!(
    /// `/vision/mask`: a mask from the segmentation source; `timestamp` is the
    /// frame it was computed on, `log_time` when it arrived.
    VisionMask(RawImage), "/vision/mask", "foxglove.RawImage", Foxglove::RawImage.schema()
);
channel!(
    /// `/vision/pose`: a pose from the pose-estimation source; `timestamp` is
    /// the frame it was computed on, `log_time` when it arrived.
    VisionPose(PoseInFrame), "/vision/pose", "foxglove.PoseInFrame", Foxglove::PoseInFrame.schema()
);
channel!(
    /// `/estimate/pose/maskukf`: MaskUKF's `camera_from_object`.
    MaskUkfPose(PoseInFrame), "/estimate/pose/maskukf", "foxglove.PoseInFrame", Foxglove::PoseInFrame.schema()
);
channel!(
    /// `/estimate/pose/roft`: ROFT's `camera_from_object`.
    RoftPose(PoseInFrame), "/estimate/pose/roft", "foxglove.PoseInFrame", Foxglove::PoseInFrame.schema()
);
channel!(
    /// `/estimate/transform/maskukf`: MaskUKF's object frame for the 3D panel.
    MaskUkfTransform(FrameTransform), "/estimate/transform/maskukf", "foxglove.FrameTransform",
    Foxglove::FrameTransform.schema()
);
channel!(
    /// `/estimate/transform/roft`: ROFT's object frame for the 3D panel.
    RoftTransform(FrameTransform), "/estimate/transform/roft", "foxglove.FrameTransform",
    Foxglove::FrameTransform.schema()
);
channel!(
    /// `/estimate/velocity/maskukf`: MaskUKF's velocity.
    MaskUkfVelocity(VelocityEstimate), "/estimate/velocity/maskukf", "slidetrack.VelocityEstimate",
    derived::<VelocityEstimate>("slidetrack.VelocityEstimate")
);
channel!(
    /// `/estimate/velocity/roft`: ROFT's velocity.
    RoftVelocity(VelocityEstimate), "/estimate/velocity/roft", "slidetrack.VelocityEstimate",
    derived::<VelocityEstimate>("slidetrack.VelocityEstimate")
);

/// The channel specs of this module, in the order of `docs/session-format.md`
/// (`/rgbd/depth`, of the `depth` module, comes after `/rgbd/color`).
pub fn vision_channel_specs() -> Vec<ChannelSpec> {
    vec![
        ChannelSpec::of::<RgbdColor>(),
        ChannelSpec::of::<RgbdCalibration>(),
        ChannelSpec::of::<RgbdMask>(),
        ChannelSpec::of::<ObjectTruth>(),
        ChannelSpec::of::<VisionMask>(),
        ChannelSpec::of::<VisionPose>(),
        ChannelSpec::of::<MaskUkfPose>(),
        ChannelSpec::of::<MaskUkfTransform>(),
        ChannelSpec::of::<MaskUkfVelocity>(),
        ChannelSpec::of::<RoftPose>(),
        ChannelSpec::of::<RoftTransform>(),
        ChannelSpec::of::<RoftVelocity>(),
        ChannelSpec::of::<super::odometry::MaskUkfOdometry>(),
        ChannelSpec::of::<super::odometry::RoftOdometry>(),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn depth_and_masks_round_trip_through_raw_images() {
        let depth = DepthImage { width: 3, height: 2, data: vec![0, 1, 2, 30000, 65535, 7], scale_m: 0.0001 };
        let raw = RawImage::depth(TimeNs(5), "camera", &depth);
        let json = serde_json::to_string(&raw).unwrap();
        let back: RawImage = serde_json::from_str(&json).unwrap();
        let mm = back.to_depth().unwrap();
        assert_eq!(mm.data, vec![0, 0, 0, 3000, 6554, 1]);
        let mask = RawImage::mask(TimeNs(5), "camera", 2, 2, &[0, 1, 0, 7]);
        assert_eq!(mask.to_mask().unwrap(), vec![0, 255, 0, 255]);
        assert!(mask.to_depth().is_none());
    }

    #[test]
    fn poses_round_trip_and_refuse_nan() {
        let p = Isometry3::from_parts(
            Translation3::new(0.1, 0.2, 0.3),
            UnitQuaternion::from_euler_angles(0.1, 0.2, 0.3),
        );
        let msg = PoseInFrame::new(TimeNs(1), "camera", &p);
        let back = msg.pose.to_isometry().unwrap();
        assert!((back.translation.vector - p.translation.vector).norm() < 1e-12);
        assert!(back.rotation.angle_to(&p.rotation) < 1e-12);
        let mut bad = msg.pose;
        bad.position.x = f64::NAN;
        assert!(bad.to_isometry().is_none());
        bad = msg.pose;
        bad.orientation = Quaternion::default();
        assert!(bad.to_isometry().is_none());
    }
}
