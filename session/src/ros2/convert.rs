//! A session message as a ROS 2 message: its type and its CDR bytes.
//!
//! | session schema | ROS 2 type | header |
//! |---|---|---|
//! | `slidetrack.TactileRaw` | `slidetrack_msgs/msg/TactileRaw` | log time, no frame |
//! | `slidetrack.HandState` | `slidetrack_msgs/msg/HandState` | log time, no frame |
//! | `slidetrack.SlidingEstimate` | `slidetrack_msgs/msg/SlidingEstimate` | log time, no frame |
//! | `foxglove.CompressedImage` | `sensor_msgs/msg/CompressedImage` | the image's time and frame |
//! | `foxglove.RawImage` | `sensor_msgs/msg/Image` | the image's time and frame |
//! | `foxglove.CameraCalibration` | `sensor_msgs/msg/CameraInfo` | its time and frame |
//! | `foxglove.FrameTransform` | `tf2_msgs/msg/TFMessage` (on `/tf`) | its time, parent frame |
//! | `foxglove.PoseInFrame` (the vision trackers' poses) | `geometry_msgs/msg/PoseStamped` | its time and frame |
//! | `slidetrack.VelocityEstimate` (their velocities) | `geometry_msgs/msg/TwistStamped` | log time, its frame |
//! | `slidetrack.Odometry` (their estimates with covariance) | `nav_msgs/msg/Odometry` | log time, its frame |
//! | `slidetrack.PlanarEstimate` | `slidetrack_msgs/msg/PlanarEstimate` | log time, no frame |
//!
//! Every other schema has no ROS 2 counterpart here and is left out.

use serde::de::DeserializeOwned;
use slidetrack_core::TimeNs;

use super::cdr::CdrWriter;
use crate::estimates::SlidingEstimate;
use crate::in_hand::PlanarEstimate;
use crate::messages::{HandState, TactileRaw};
use crate::odometry::Odometry;
use crate::vision::{CameraCalibration, CompressedImage, FoxgloveTime};
use crate::vision_pose::{FrameTransform, PoseInFrame, RawImage, VelocityEstimate};

/// A converted message.
#[derive(Clone, Debug, PartialEq)]
pub struct Ros2Message {
    /// The ROS 2 type (`pkg/msg/Type`).
    pub ros_type: &'static str,
    /// The topic in the bag (the session's, or `/tf` for transforms).
    pub topic: String,
    /// The CDR-encoded message.
    pub data: Vec<u8>,
}

/// The ROS 2 type and topic a message of `schema` on `topic` converts to;
/// `None` for a schema without a ROS 2 counterpart (see the module table).
pub fn ros2_type<'a>(schema: &str, topic: &'a str) -> Option<(&'static str, &'a str)> {
    Some(match schema {
        "slidetrack.TactileRaw" => ("slidetrack_msgs/msg/TactileRaw", topic),
        "slidetrack.HandState" => ("slidetrack_msgs/msg/HandState", topic),
        "slidetrack.SlidingEstimate" => ("slidetrack_msgs/msg/SlidingEstimate", topic),
        "foxglove.CompressedImage" => ("sensor_msgs/msg/CompressedImage", topic),
        "foxglove.RawImage" => ("sensor_msgs/msg/Image", topic),
        "foxglove.CameraCalibration" => ("sensor_msgs/msg/CameraInfo", topic),
        "foxglove.FrameTransform" => ("tf2_msgs/msg/TFMessage", "/tf"),
        "foxglove.PoseInFrame" => ("geometry_msgs/msg/PoseStamped", topic),
        "slidetrack.VelocityEstimate" => ("geometry_msgs/msg/TwistStamped", topic),
        "slidetrack.Odometry" => ("nav_msgs/msg/Odometry", topic),
        "slidetrack.PlanarEstimate" => ("slidetrack_msgs/msg/PlanarEstimate", topic),
        _ => return None,
    })
}

/// Converts one message of `schema` on `topic` logged at `log_time`;
/// `Ok(None)` for a schema without a ROS 2 counterpart, `Err` with the JSON
/// error when the payload does not decode as its schema.
pub fn convert(
    schema: &str,
    topic: &str,
    log_time: TimeNs,
    json: &[u8],
) -> Result<Option<Ros2Message>, serde_json::Error> {
    let Some((ros_type, topic)) = ros2_type(schema, topic) else { return Ok(None) };
    let mut w = CdrWriter::new();
    match schema {
        "slidetrack.TactileRaw" => tactile_raw(&mut w, log_time, &decode(json)?),
        "slidetrack.HandState" => hand_state(&mut w, log_time, &decode(json)?),
        "slidetrack.SlidingEstimate" => {
            let e: SlidingEstimate = decode(json)?;
            header(&mut w, stamp_of(log_time), "");
            w.f64(e.position).f64(e.velocity).f64_array(e.covariance.as_flattened());
        }
        "foxglove.CompressedImage" => {
            let m: CompressedImage = decode(json)?;
            header(&mut w, m.timestamp, &m.frame_id);
            w.string(&m.format).bytes(&m.data);
        }
        "foxglove.RawImage" => {
            let m: RawImage = decode(json)?;
            header(&mut w, m.timestamp, &m.frame_id);
            // Foxglove's raw images are little-endian (is_bigendian 0).
            w.u32(m.height).u32(m.width).string(&m.encoding).u8(0).u32(m.step).bytes(&m.data);
        }
        "foxglove.CameraCalibration" => camera_info(&mut w, &decode(json)?),
        "foxglove.FrameTransform" => {
            let m: FrameTransform = decode(json)?;
            w.seq_len(1);
            header(&mut w, m.timestamp, &m.parent_frame_id);
            w.string(&m.child_frame_id);
            w.f64(m.translation.x).f64(m.translation.y).f64(m.translation.z);
            w.f64(m.rotation.x).f64(m.rotation.y).f64(m.rotation.z).f64(m.rotation.w);
        }
        "foxglove.PoseInFrame" => {
            let m: PoseInFrame = decode(json)?;
            header(&mut w, m.timestamp, &m.frame_id);
            let (p, q) = (m.pose.position, m.pose.orientation);
            w.f64(p.x).f64(p.y).f64(p.z).f64(q.x).f64(q.y).f64(q.z).f64(q.w);
        }
        "slidetrack.VelocityEstimate" => {
            let m: VelocityEstimate = decode(json)?;
            header(&mut w, stamp_of(log_time), &m.frame_id);
            let [vx, vy, vz] = m.linear_velocity_mps;
            let [wx, wy, wz] = m.angular_velocity_radps;
            w.f64(vx).f64(vy).f64(vz).f64(wx).f64(wy).f64(wz);
        }
        "slidetrack.Odometry" => odometry(&mut w, log_time, &decode(json)?)?,
        "slidetrack.PlanarEstimate" => {
            let m: PlanarEstimate = decode(json)?;
            header(&mut w, stamp_of(log_time), "");
            let s = &m.state;
            w.f64_array(&s.translation_m).f64(s.rotation_rad);
            w.f64_array(&s.velocity_m_per_s).f64(s.angular_velocity_rad_per_s);
            w.f64_array(covariance_36("covariance", &m.covariance)?);
        }
        _ => return Ok(None),
    }
    Ok(Some(Ros2Message { ros_type, topic: topic.to_string(), data: w.finish() }))
}

fn decode<T: DeserializeOwned>(json: &[u8]) -> Result<T, serde_json::Error> {
    serde_json::from_slice(json)
}

/// A `float64[36]` covariance: exactly 36 values, else the JSON error of a
/// payload that does not match its schema.
fn covariance_36<'a>(field: &str, values: &'a [f64]) -> Result<&'a [f64], serde_json::Error> {
    if values.len() == 36 {
        Ok(values)
    } else {
        Err(serde::de::Error::custom(format!("{field}: {} values, a 6x6 covariance has 36", values.len())))
    }
}

/// `nav_msgs/Odometry`: header, `child_frame_id`, `PoseWithCovariance`
/// (`Pose`, `float64[36]`), `TwistWithCovariance` (`Twist`, `float64[36]`).
fn odometry(w: &mut CdrWriter, log_time: TimeNs, m: &Odometry) -> Result<(), serde_json::Error> {
    let (pose_covariance, twist_covariance) = (
        covariance_36("pose_covariance", &m.pose_covariance)?,
        covariance_36("twist_covariance", &m.twist_covariance)?,
    );
    header(w, stamp_of(log_time), &m.frame_id);
    w.string(&m.child_frame_id);
    let ([x, y, z], q) = (m.position_m, m.orientation);
    w.f64(x).f64(y).f64(z).f64(q.x).f64(q.y).f64(q.z).f64(q.w).f64_array(pose_covariance);
    let ([vx, vy, vz], [wx, wy, wz]) = (m.linear_velocity_in_child_mps, m.angular_velocity_in_child_radps);
    w.f64(vx).f64(vy).f64(vz).f64(wx).f64(wy).f64(wz).f64_array(twist_covariance);
    Ok(())
}

/// A session-clock time as `builtin_interfaces/Time`.
fn stamp_of(t: TimeNs) -> FoxgloveTime {
    // The session clock starts at 0: whole seconds fit an i32 for 68 years.
    FoxgloveTime {
        sec: u32::try_from(t.0 / 1_000_000_000).unwrap_or(u32::MAX),
        nsec: (t.0 % 1_000_000_000) as u32,
    }
}

/// `std_msgs/Header`: `builtin_interfaces/Time` (`int32 sec`, `uint32 nanosec`) and `frame_id`.
fn header(w: &mut CdrWriter, stamp: FoxgloveTime, frame_id: &str) {
    w.i32(i32::try_from(stamp.sec).unwrap_or(i32::MAX)).u32(stamp.nsec).string(frame_id);
}

fn tactile_raw(w: &mut CdrWriter, log_time: TimeNs, m: &TactileRaw) {
    header(w, stamp_of(log_time), "");
    w.u64(m.sequence).seq_len(m.sensors.len());
    for sensor in &m.sensors {
        let axis =
            |f: fn(&crate::messages::Xyz<u16>) -> u16| sensor.taxels.iter().map(f).collect::<Vec<u16>>();
        w.string(&sensor.name).u16_seq(&axis(|t| t.x)).u16_seq(&axis(|t| t.y)).u16_seq(&axis(|t| t.z));
    }
}

fn hand_state(w: &mut CdrWriter, log_time: TimeNs, m: &HandState) {
    header(w, stamp_of(log_time), "");
    w.f64_seq(&m.finger_travel).bool(m.opening.is_some()).f64(m.opening.unwrap_or(0.0));
    let g = m.gripper.unwrap_or_default();
    w.bool(m.gripper.is_some());
    w.bool(g.activated).u8(g.object).u8(g.fault).u16(g.requested).u16(g.position).u32(g.current_ma);
}

fn camera_info(w: &mut CdrWriter, m: &CameraCalibration) {
    header(w, m.timestamp, &m.frame_id);
    w.u32(m.height).u32(m.width).string(&m.distortion_model).f64_seq(&m.d);
    w.f64_array(&m.k).f64_array(&m.r).f64_array(&m.p);
    // binning_x, binning_y: 0 (no binning); roi: all zero (the full image).
    w.u32(0).u32(0);
    w.u32(0).u32(0).u32(0).u32(0).bool(false);
}

#[cfg(test)]
mod tests {
    use super::*;

    fn bytes(hex: &str) -> Vec<u8> {
        (0..hex.len()).step_by(2).map(|i| u8::from_str_radix(&hex[i..i + 2], 16).unwrap()).collect()
    }

    fn cdr(schema: &str, t: u64, json: &str) -> Ros2Message {
        convert(schema, "/x", TimeNs(t), json.as_bytes()).unwrap().unwrap()
    }

    // The expected bytes are what rosbags 0.11.9 (`Typestore.serialize_cdr`,
    // slidetrack_msgs registered from session/ros2/slidetrack_msgs/msg;
    // the standard types from its ROS 2 Humble store) writes for the same
    // values.

    #[test]
    fn an_estimate_is_rosbags_bytes() {
        let m = cdr(
            "slidetrack.SlidingEstimate",
            1_000_000_002,
            r#"{"position":0.5,"velocity":-1.0,"covariance":[[1.0,2.0],[3.0,4.0]]}"#,
        );
        assert_eq!(m.ros_type, "slidetrack_msgs/msg/SlidingEstimate");
        let expected = "0001000001000000020000000100000000000000000000000000e03f000000000000f0bf\
                        000000000000f03f000000000000004000000000000008400000000000001040";
        assert_eq!(m.data, bytes(expected));
    }

    #[test]
    fn a_tactile_scan_is_rosbags_bytes() {
        let json =
            r#"{"sequence":7,"sensors":[{"name":"th","taxels":[{"x":1,"y":3,"z":5},{"x":2,"y":4,"z":6}]}]}"#;
        let m = cdr("slidetrack.TactileRaw", 5, json);
        let expected = "00010000000000000500000001000000000000000700000000000000010000000300000074680000\
                        020000000100020002000000030004000200000005000600";
        assert_eq!(m.data, bytes(expected));
    }

    #[test]
    fn a_hand_state_is_rosbags_bytes() {
        let m = cdr("slidetrack.HandState", 5, r#"{"finger_travel":[0.1],"opening":0.02,"gripper":null}"#);
        let expected = "000100000000000005000000010000000000000001000000000000009a9999999999b93f0100000000000000\
                        7b14ae47e17a943f000000000000000000000000";
        assert_eq!(m.data, bytes(expected));
    }

    #[test]
    fn a_camera_calibration_is_rosbags_camera_info() {
        let json = r#"{"timestamp":{"sec":1,"nsec":2},"frame_id":"cam","width":3,"height":2,
            "distortion_model":"plumb_bob","D":[0.1,0.2,0.0,0.0,0.3],"K":[0,1,2,3,4,5,6,7,8],
            "R":[1,0,0,0,1,0,0,0,1],"P":[0,1,2,3,4,5,6,7,8,9,10,11]}"#;
        let m = cdr("foxglove.CameraCalibration", 5, json);
        assert_eq!(m.ros_type, "sensor_msgs/msg/CameraInfo");
        let expected = concat!(
            "0001000001000000020000000400000063616d0002000000030000000a000000706c756d625f626f6200000005000000",
            "000000009a9999999999b93f9a9999999999c93f00000000000000000000000000000000333333333333d33f",
            "0000000000000000000000000000f03f000000000000004000000000000008400000000000001040",
            "000000000000144000000000000018400000000000001c400000000000002040000000000000f03f",
            "000000000000000000000000000000000000000000000000000000000000f03f0000000000000000",
            "00000000000000000000000000000000000000000000f03f0000000000000000000000000000f03f",
            "000000000000004000000000000008400000000000001040000000000000144000000000000018400000000000001c40",
            "000000000000204000000000000022400000000000002440000000000000264000000000000000000000000000000000",
            "000000000000000000",
        );
        assert_eq!(m.data, bytes(expected));
    }

    #[test]
    fn a_vision_pose_is_rosbags_pose_stamped() {
        let json = r#"{"timestamp":{"sec":1,"nsec":2},"frame_id":"camera","pose":{
            "position":{"x":0.1,"y":-0.2,"z":0.5},"orientation":{"x":0.0,"y":0.0,"z":0.6,"w":0.8}}}"#;
        let m = cdr("foxglove.PoseInFrame", 5, json);
        assert_eq!((m.ros_type, m.topic.as_str()), ("geometry_msgs/msg/PoseStamped", "/x"));
        let expected = "0001000001000000020000000700000063616d6572610000000000009a9999999999b93f9a9999999999c9bf\
                        000000000000e03f00000000000000000000000000000000333333333333e33f9a9999999999e93f";
        assert_eq!(m.data, bytes(expected));
    }

    #[test]
    fn a_vision_velocity_is_rosbags_twist_stamped_at_its_log_time() {
        let json = r#"{"frame_id":"camera","linear_velocity_mps":[0.01,0.02,-0.03],
            "angular_velocity_radps":[0.1,0.0,-0.2]}"#;
        let m = cdr("slidetrack.VelocityEstimate", 5, json);
        assert_eq!(m.ros_type, "geometry_msgs/msg/TwistStamped");
        let expected = "0001000000000000050000000700000063616d6572610000000000007b14ae47e17a843f7b14ae47e17a943f\
                        b81e85eb51b89ebf9a9999999999b93f00000000000000009a9999999999c9bf";
        assert_eq!(m.data, bytes(expected));
    }

    #[test]
    fn transforms_go_to_tf_and_unknown_schemas_are_left_out() {
        let json = r#"{"timestamp":{"sec":1,"nsec":2},"parent_frame_id":"camera","child_frame_id":"object",
            "translation":{"x":1.0,"y":2.0,"z":3.0},"rotation":{"x":0.0,"y":0.0,"z":0.0,"w":1.0}}"#;
        let m = cdr("foxglove.FrameTransform", 5, json);
        assert_eq!((m.ros_type, m.topic.as_str()), ("tf2_msgs/msg/TFMessage", "/tf"));
        let expected = "000100000100000001000000020000000700000063616d6572610000070000006f626a656374000000000000\
                        000000000000f03f000000000000004000000000000008400000000000000000000000000000000000000000\
                        00000000000000000000f03f";
        assert_eq!(m.data, bytes(expected));
        assert_eq!(convert("slidetrack.SimTruth", "/sim/truth", TimeNs(0), b"{}").unwrap(), None);
        assert!(convert("slidetrack.TactileRaw", "/tactile/raw", TimeNs(0), b"{\"sequence\":1}").is_err());
    }

    #[test]
    fn a_vision_estimate_with_covariance_is_rosbags_odometry_at_its_log_time() {
        let (pose_cov, twist_cov): (Vec<f64>, Vec<f64>) =
            (0..36).map(|k| (0.5 * f64::from(k), -f64::from(k))).unzip();
        let json = serde_json::json!({
            "frame_id": "camera", "child_frame_id": "object/maskukf",
            "position_m": [0.1, -0.2, 0.5], "orientation": {"x": 0.0, "y": 0.0, "z": 0.6, "w": 0.8},
            "pose_covariance": pose_cov,
            "linear_velocity_in_child_mps": [0.01, 0.02, -0.03], "angular_velocity_in_child_radps": [0.1, 0.0, -0.2],
            "twist_covariance": twist_cov,
        });
        let m = cdr("slidetrack.Odometry", 5, &json.to_string());
        assert_eq!(m.ros_type, "nav_msgs/msg/Odometry");
        let expected = concat!(
            "0001000000000000050000000700000063616d65726100000f0000006f626a6563742f6d61736b756b6600009a999999",
            "9999b93f9a9999999999c9bf000000000000e03f00000000000000000000000000000000333333333333e33f9a999999",
            "9999e93f0000000000000000000000000000e03f000000000000f03f000000000000f83f000000000000004000000000",
            "0000044000000000000008400000000000000c4000000000000010400000000000001240000000000000144000000000",
            "0000164000000000000018400000000000001a400000000000001c400000000000001e40000000000000204000000000",
            "000021400000000000002240000000000000234000000000000024400000000000002540000000000000264000000000",
            "00002740000000000000284000000000000029400000000000002a400000000000002b400000000000002c4000000000",
            "00002d400000000000002e400000000000002f4000000000000030400000000000803040000000000000314000000000",
            "008031407b14ae47e17a843f7b14ae47e17a943fb81e85eb51b89ebf9a9999999999b93f00000000000000009a999999",
            "9999c9bf0000000000000080000000000000f0bf00000000000000c000000000000008c000000000000010c000000000",
            "000014c000000000000018c00000000000001cc000000000000020c000000000000022c000000000000024c000000000",
            "000026c000000000000028c00000000000002ac00000000000002cc00000000000002ec000000000000030c000000000",
            "000031c000000000000032c000000000000033c000000000000034c000000000000035c000000000000036c000000000",
            "000037c000000000000038c000000000000039c00000000000003ac00000000000003bc00000000000003cc000000000",
            "00003dc00000000000003ec00000000000003fc000000000000040c000000000008040c000000000000041c000000000",
            "008041c0",
        );
        assert_eq!(m.data, bytes(expected));
    }

    #[test]
    fn a_planar_estimate_is_rosbags_bytes() {
        let covariance: Vec<f64> = (0..36).map(f64::from).collect();
        let json = serde_json::json!({
            "state": {"translation_m": [0.001, -0.002], "rotation_rad": 0.05, "velocity_m_per_s": [0.01, 0.0],
                      "angular_velocity_rad_per_s": -0.5},
            "covariance": covariance,
        });
        let m = cdr("slidetrack.PlanarEstimate", 1_000_000_002, &json.to_string());
        assert_eq!(m.ros_type, "slidetrack_msgs/msg/PlanarEstimate");
        let expected = concat!(
            "0001000001000000020000000100000000000000fca9f1d24d62503ffca9f1d24d6260bf9a9999999999a93f7b14ae47",
            "e17a843f0000000000000000000000000000e0bf0000000000000000000000000000f03f000000000000004000000000",
            "000008400000000000001040000000000000144000000000000018400000000000001c40000000000000204000000000",
            "000022400000000000002440000000000000264000000000000028400000000000002a400000000000002c4000000000",
            "00002e400000000000003040000000000000314000000000000032400000000000003340000000000000344000000000",
            "0000354000000000000036400000000000003740000000000000384000000000000039400000000000003a4000000000",
            "00003b400000000000003c400000000000003d400000000000003e400000000000003f40000000000000404000000000",
            "0080404000000000000041400000000000804140",
        );
        assert_eq!(m.data, bytes(expected));
    }

    /// A covariance that is not 6 x 6 is the payload's error, not a short
    /// `float64[36]` that would shift every later field.
    #[test]
    fn a_covariance_without_36_values_is_an_error() {
        let json = r#"{"state":{"translation_m":[0,0],"rotation_rad":0,"velocity_m_per_s":[0,0],
            "angular_velocity_rad_per_s":0},"covariance":[1.0,2.0]}"#;
        let err = convert("slidetrack.PlanarEstimate", "/x", TimeNs(0), json.as_bytes()).unwrap_err();
        assert!(err.to_string().contains("covariance: 2 values"), "{err}");
    }
}
