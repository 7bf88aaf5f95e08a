//! ROS 2 names on DDS, as ROS 2's DDS middlewares (`rmw_cyclonedds`,
//! `rmw_fastrtps`) map them (ROS 2 design article "Topic and Service name
//! mapping to DDS"): topic `/a/b` is DDS topic `rt/a/b`; message type
//! `pkg/msg/Type` is DDS type `pkg::msg::dds_::Type_`.

/// The DDS topic of the ROS 2 topic `topic` (`/tactile/raw` -> `rt/tactile/raw`).
pub fn dds_topic(topic: &str) -> String {
    format!("rt/{}", topic.trim_start_matches('/'))
}

/// The DDS type of the ROS 2 type `ros_type`
/// (`sensor_msgs/msg/Image` -> `sensor_msgs::msg::dds_::Image_`); a name
/// not of the form `pkg/msg/Type` is returned with `/` as `::`.
pub fn dds_type(ros_type: &str) -> String {
    match ros_type.split('/').collect::<Vec<_>>()[..] {
        [package, kind, name] => format!("{package}::{kind}::dds_::{name}_"),
        _ => ros_type.replace('/', "::"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_are_what_ros_2_middlewares_use() {
        assert_eq!(dds_topic("/tactile/raw"), "rt/tactile/raw");
        assert_eq!(dds_topic("/tf"), "rt/tf");
        assert_eq!(dds_type("tf2_msgs/msg/TFMessage"), "tf2_msgs::msg::dds_::TFMessage_");
        assert_eq!(
            dds_type("slidetrack_msgs/msg/SlidingEstimate"),
            "slidetrack_msgs::msg::dds_::SlidingEstimate_"
        );
    }
}
