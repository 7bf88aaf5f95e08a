//! The camera channels: images and intrinsics in Foxglove's schemas (so
//! Foxglove shows them), and the ArUco detections.

use base64::Engine as _;
use base64::engine::general_purpose::STANDARD as BASE64;
use serde::{Deserialize, Deserializer, Serialize, Serializer};
use serde_json::Value;
use slidetrack_core::{CameraIntrinsics, EncodedImage, TimeNs};

use super::channel::ChannelMessage;
use super::schema::{Foxglove, derived};

/// Foxglove's `time`: seconds and nanoseconds, here on the session clock.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct FoxgloveTime {
    /// Whole seconds.
    pub sec: u32,
    /// Nanoseconds within the second, `0..=999_999_999`.
    pub nsec: u32,
}

impl From<TimeNs> for FoxgloveTime {
    fn from(t: TimeNs) -> FoxgloveTime {
        let sec = u32::try_from(t.0 / 1_000_000_000).unwrap_or(u32::MAX);
        FoxgloveTime { sec, nsec: (t.0 % 1_000_000_000) as u32 }
    }
}

impl From<FoxgloveTime> for TimeNs {
    fn from(t: FoxgloveTime) -> TimeNs {
        TimeNs(u64::from(t.sec) * 1_000_000_000 + u64::from(t.nsec))
    }
}

/// `/camera/image`: one compressed camera frame (`foxglove.CompressedImage`).
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct CompressedImage {
    /// Acquisition time on the session clock.
    pub timestamp: FoxgloveTime,
    /// The camera's optical frame.
    pub frame_id: String,
    /// The compressed bytes (base64 in JSON).
    #[serde(serialize_with = "to_base64", deserialize_with = "from_base64")]
    pub data: Vec<u8>,
    /// `jpeg` or `png`.
    pub format: String,
}

impl CompressedImage {
    /// A frame acquired at `t`, as the camera delivered it.
    pub fn new(t: TimeNs, frame_id: &str, image: &EncodedImage) -> CompressedImage {
        CompressedImage {
            timestamp: t.into(),
            frame_id: frame_id.to_string(),
            data: image.bytes.clone(),
            format: image.format.clone(),
        }
    }

    /// The message as JSON: the bytes of `serde_json::to_vec`, made without
    /// serde_json's scan of the base64 data for characters to escape (base64
    /// has none). The image encoder's thread writes 30-40 kB of it per frame,
    /// and the scan was about 1 % of a simulated trial's CPU time.
    pub fn to_json(&self) -> Result<Vec<u8>, serde_json::Error> {
        // `{"timestamp":..,"frame_id":..,"data":"","format":..}`: the data
        // goes between the quotes before the format, the last field.
        let shell = CompressedImage {
            timestamp: self.timestamp,
            frame_id: self.frame_id.clone(),
            data: Vec::new(),
            format: self.format.clone(),
        };
        let mut json = serde_json::to_vec(&shell)?;
        let tail = [&b"\",\"format\":"[..], &serde_json::to_vec(&self.format)?, b"}"].concat();
        let head_len = json.len().saturating_sub(tail.len());
        if !(json.ends_with(&tail) && json[..head_len].ends_with(b"\"data\":\"")) {
            return serde_json::to_vec(self);
        }
        let tail = json.split_off(head_len);
        let start = json.len();
        json.resize(start + 4 * self.data.len().div_ceil(3), 0);
        let Ok(written) = BASE64.encode_slice(&self.data, &mut json[start..]) else {
            return serde_json::to_vec(self);
        };
        json.truncate(start + written);
        json.extend_from_slice(&tail);
        Ok(json)
    }
}

fn to_base64<S: Serializer>(bytes: &[u8], s: S) -> Result<S::Ok, S::Error> {
    s.serialize_str(&BASE64.encode(bytes))
}

fn from_base64<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<u8>, D::Error> {
    let s = <std::borrow::Cow<'de, str>>::deserialize(d)?;
    BASE64.decode(s.as_bytes()).map_err(serde::de::Error::custom)
}

impl ChannelMessage for CompressedImage {
    const TOPIC: &'static str = "/camera/image";
    const SCHEMA_NAME: &'static str = "foxglove.CompressedImage";
    fn json_schema() -> Value {
        Foxglove::CompressedImage.schema()
    }
}

/// `/camera/calibration`: the intrinsics in use (`foxglove.CameraCalibration`,
/// plumb-bob distortion).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct CameraCalibration {
    /// Time from which the calibration applies, on the session clock.
    pub timestamp: FoxgloveTime,
    /// The camera's optical frame.
    pub frame_id: String,
    /// Image width (px).
    pub width: u32,
    /// Image height (px).
    pub height: u32,
    /// Always `plumb_bob`.
    pub distortion_model: String,
    /// `[k1, k2, p1, p2, k3]`, dimensionless.
    #[serde(rename = "D")]
    pub d: Vec<f64>,
    /// Camera matrix (px), 3x3 row-major.
    #[serde(rename = "K")]
    pub k: [f64; 9],
    /// Rectification matrix: identity for a monocular camera, 3x3 row-major.
    #[serde(rename = "R")]
    pub r: [f64; 9],
    /// Projection matrix (px), 3x4 row-major: `[K | 0]`.
    #[serde(rename = "P")]
    pub p: [f64; 12],
}

impl CameraCalibration {
    /// The calibration message of `intrinsics`, valid from `t`.
    pub fn new(t: TimeNs, frame_id: &str, intrinsics: &CameraIntrinsics) -> CameraCalibration {
        let c = intrinsics;
        #[rustfmt::skip]
        let p = [
            c.fx, 0.0,  c.cx, 0.0,
            0.0,  c.fy, c.cy, 0.0,
            0.0,  0.0,  1.0,  0.0,
        ];
        CameraCalibration {
            timestamp: t.into(),
            frame_id: frame_id.to_string(),
            width: c.width,
            height: c.height,
            distortion_model: "plumb_bob".to_string(),
            d: c.distortion.to_vec(),
            k: c.k(),
            r: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
            p,
        }
    }

    /// The intrinsics back, or `None` unless the model is `plumb_bob` with 5 coefficients.
    pub fn intrinsics(&self) -> Option<CameraIntrinsics> {
        let distortion: [f64; 5] = self.d.as_slice().try_into().ok()?;
        (self.distortion_model == "plumb_bob").then_some(CameraIntrinsics {
            width: self.width,
            height: self.height,
            fx: self.k[0],
            fy: self.k[4],
            cx: self.k[2],
            cy: self.k[5],
            distortion,
        })
    }
}

impl From<&CameraIntrinsics> for CameraCalibration {
    /// Valid from the session start, in frame `camera`.
    fn from(intrinsics: &CameraIntrinsics) -> CameraCalibration {
        CameraCalibration::new(TimeNs::ZERO, "camera", intrinsics)
    }
}

impl ChannelMessage for CameraCalibration {
    const TOPIC: &'static str = "/camera/calibration";
    const SCHEMA_NAME: &'static str = "foxglove.CameraCalibration";
    fn json_schema() -> Value {
        Foxglove::CameraCalibration.schema()
    }
}

/// A rotation as a unit quaternion.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct Quaternion {
    /// Vector part, x.
    pub x: f64,
    /// Vector part, y.
    pub y: f64,
    /// Vector part, z.
    pub z: f64,
    /// Scalar part.
    pub w: f64,
}

/// `/aruco/detections`: the marker on the object in one camera frame. A missed
/// detection is a message with `detected: false` and every other field `null`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct ArucoDetection {
    /// True when the marker was found.
    pub detected: bool,
    /// The marker's dictionary id.
    pub marker_id: Option<u32>,
    /// The four corners in the distorted image (px), in ArUco order
    /// (top-left, top-right, bottom-right, bottom-left), each `[u, v]`.
    pub corners_px: Option<[[f64; 2]; 4]>,
    /// Marker centre in the camera frame (m).
    pub position_in_camera_m: Option<[f64; 3]>,
    /// Marker orientation in the camera frame (`camera_from_marker` rotation).
    pub orientation_in_camera: Option<Quaternion>,
    /// Marker centre projected on the sliding axis (m).
    pub position_on_axis_m: Option<f64>,
    /// RMS reprojection error of the corners (px).
    pub reprojection_error_px: Option<f64>,
}

impl ArucoDetection {
    /// A frame in which the marker was not found.
    pub fn missed() -> ArucoDetection {
        ArucoDetection::default()
    }
}

impl ChannelMessage for ArucoDetection {
    const TOPIC: &'static str = "/aruco/detections";
    const SCHEMA_NAME: &'static str = "slidetrack.ArucoDetection";
    fn json_schema() -> Value {
        derived::<Self>(Self::SCHEMA_NAME)
    }
}
