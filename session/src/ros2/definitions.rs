//! The ROS 2 message definitions of a bag: standard types and slidetrack's
//! own, and their complete definitions in the `ros2msg` schema encoding.
//!
//! The standard definitions are the fields of the `.msg` files of
//! ros2/common_interfaces (commit `c0c0bc57f958eb54a142446f0c2a475754367eee`)
//! and of `builtin_interfaces/msg/Time` (ros2/rcl_interfaces), comments left
//! out. slidetrack's own are the files of `session/ros2/slidetrack_msgs/msg/`.
//!
//! A complete definition (MCAP format registry, `ros2msg`; rosbag2's
//! `docs/message_definition_encoding.md`) is the type's own text, then each
//! type it uses, directly or not, once: a line of 80 `=`, a line
//! `MSG: pkg/msg/Type`, and that type's text.

/// `(name, text)` of every message type a bag may use.
const DEFINITIONS: &[(&str, &str)] = &[
    ("builtin_interfaces/msg/Time", "int32 sec\nuint32 nanosec\n"),
    ("std_msgs/msg/Header", "builtin_interfaces/Time stamp\nstring frame_id\n"),
    ("sensor_msgs/msg/CompressedImage", "std_msgs/Header header\nstring format\nuint8[] data\n"),
    (
        "sensor_msgs/msg/Image",
        "std_msgs/Header header\nuint32 height\nuint32 width\nstring encoding\nuint8 is_bigendian\nuint32 step\nuint8[] data\n",
    ),
    (
        "sensor_msgs/msg/CameraInfo",
        "std_msgs/Header header\nuint32 height\nuint32 width\nstring distortion_model\nfloat64[] d\n\
         float64[9] k\nfloat64[9] r\nfloat64[12] p\nuint32 binning_x\nuint32 binning_y\nRegionOfInterest roi\n",
    ),
    (
        "sensor_msgs/msg/RegionOfInterest",
        "uint32 x_offset\nuint32 y_offset\nuint32 height\nuint32 width\nbool do_rectify\n",
    ),
    ("geometry_msgs/msg/Vector3", "float64 x\nfloat64 y\nfloat64 z\n"),
    ("geometry_msgs/msg/Quaternion", "float64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1\n"),
    ("geometry_msgs/msg/Transform", "Vector3 translation\nQuaternion rotation\n"),
    (
        "geometry_msgs/msg/TransformStamped",
        "std_msgs/Header header\nstring child_frame_id\nTransform transform\n",
    ),
    ("tf2_msgs/msg/TFMessage", "geometry_msgs/TransformStamped[] transforms\n"),
    ("geometry_msgs/msg/Point", "float64 x\nfloat64 y\nfloat64 z\n"),
    ("geometry_msgs/msg/Pose", "Point position\nQuaternion orientation\n"),
    ("geometry_msgs/msg/PoseStamped", "std_msgs/Header header\nPose pose\n"),
    ("geometry_msgs/msg/Twist", "Vector3 linear\nVector3 angular\n"),
    ("geometry_msgs/msg/TwistStamped", "std_msgs/Header header\nTwist twist\n"),
    ("geometry_msgs/msg/PoseWithCovariance", "Pose pose\nfloat64[36] covariance\n"),
    ("geometry_msgs/msg/TwistWithCovariance", "Twist twist\nfloat64[36] covariance\n"),
    (
        "nav_msgs/msg/Odometry",
        "std_msgs/Header header\nstring child_frame_id\ngeometry_msgs/PoseWithCovariance pose\n\
         geometry_msgs/TwistWithCovariance twist\n",
    ),
    ("slidetrack_msgs/msg/TactileRaw", include_str!("../../ros2/slidetrack_msgs/msg/TactileRaw.msg")),
    (
        "slidetrack_msgs/msg/TactileSensorRaw",
        include_str!("../../ros2/slidetrack_msgs/msg/TactileSensorRaw.msg"),
    ),
    ("slidetrack_msgs/msg/HandState", include_str!("../../ros2/slidetrack_msgs/msg/HandState.msg")),
    ("slidetrack_msgs/msg/GripperState", include_str!("../../ros2/slidetrack_msgs/msg/GripperState.msg")),
    (
        "slidetrack_msgs/msg/SlidingEstimate",
        include_str!("../../ros2/slidetrack_msgs/msg/SlidingEstimate.msg"),
    ),
    ("slidetrack_msgs/msg/PlanarEstimate", include_str!("../../ros2/slidetrack_msgs/msg/PlanarEstimate.msg")),
];

/// The text of `name` (`pkg/msg/Type`).
fn text(name: &str) -> Option<&'static str> {
    DEFINITIONS.iter().find(|(n, _)| *n == name).map(|(_, t)| *t)
}

/// The full names of the message types `text` (of package `package`) uses.
fn uses(package: &str, text: &str) -> Vec<String> {
    text.lines()
        .map(|l| l.split('#').next().unwrap_or("").trim())
        .filter_map(|l| l.split_whitespace().next())
        .map(|ty| ty.split('[').next().unwrap_or(ty))
        .filter(|ty| ty.chars().next().is_some_and(|c| c.is_ascii_uppercase()) || ty.contains('/'))
        .map(|ty| match ty.split_once('/') {
            Some((pkg, name)) => format!("{pkg}/msg/{}", name.rsplit('/').next().unwrap_or(name)),
            None => format!("{package}/msg/{ty}"),
        })
        .collect()
}

/// The complete `ros2msg` definition of `name`, `None` for a type not in
/// [`DEFINITIONS`] (or using one that is not).
pub fn complete_definition(name: &str) -> Option<String> {
    let mut out = text(name)?.to_string();
    let mut done = vec![name.to_string()];
    let mut pending = uses(name.split('/').next()?, text(name)?);
    while let Some(dep) = pending.first().cloned() {
        pending.remove(0);
        if done.contains(&dep) {
            continue;
        }
        let dep_text = text(&dep)?;
        if !out.ends_with('\n') {
            out.push('\n');
        }
        out.push_str(&"=".repeat(80));
        out.push_str(&format!("\nMSG: {dep}\n{dep_text}"));
        pending.extend(uses(dep.split('/').next()?, dep_text));
        done.push(dep);
    }
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_definition_lists_each_dependency_once_after_a_delimiter() {
        let text = complete_definition("sensor_msgs/msg/CompressedImage").expect("known");
        let sep = format!("\n{}\n", "=".repeat(80));
        let parts: Vec<&str> = text.split(&sep).collect();
        assert_eq!(parts[0], "std_msgs/Header header\nstring format\nuint8[] data");
        assert_eq!(parts[1], "MSG: std_msgs/msg/Header\nbuiltin_interfaces/Time stamp\nstring frame_id");
        assert_eq!(parts[2], "MSG: builtin_interfaces/msg/Time\nint32 sec\nuint32 nanosec\n");
        assert_eq!(parts.len(), 3);
    }

    #[test]
    fn nested_and_same_package_types_are_found() {
        let tf = complete_definition("tf2_msgs/msg/TFMessage").expect("known");
        for dep in ["TransformStamped", "Transform", "Vector3", "Quaternion"] {
            assert_eq!(tf.matches(&format!("MSG: geometry_msgs/msg/{dep}\n")).count(), 1, "{dep}");
        }
        let pose = complete_definition("geometry_msgs/msg/PoseStamped").expect("known");
        for dep in ["Pose", "Point", "Quaternion"] {
            assert_eq!(pose.matches(&format!("MSG: geometry_msgs/msg/{dep}\n")).count(), 1, "{dep}");
        }
        let twist = complete_definition("geometry_msgs/msg/TwistStamped").expect("known");
        for dep in ["Twist", "Vector3"] {
            assert_eq!(twist.matches(&format!("MSG: geometry_msgs/msg/{dep}\n")).count(), 1, "{dep}");
        }
        let raw = complete_definition("slidetrack_msgs/msg/TactileRaw").expect("known");
        assert!(raw.contains("MSG: slidetrack_msgs/msg/TactileSensorRaw\n"));
        assert!(raw.contains("MSG: std_msgs/msg/Header\n"));
        // Every type used by every definition is defined.
        for (name, _) in DEFINITIONS {
            assert!(complete_definition(name).is_some(), "{name}");
        }
        assert_eq!(complete_definition("sensor_msgs/msg/PointCloud2"), None);
    }
}
