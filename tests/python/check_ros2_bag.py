"""Checks a ROS 2 bag exported by `slidetrack export --ros2-bag` with an
independent reader, the `rosbags` package, against the session it came from
(read with the official MCAP reader).

    check_ros2_bag.py BAG.mcap SESSION.mcap MSG_DIR

rosbags opens the bag (profile ros2, CDR) and deserialises every message
twice: with the definitions the bag carries (its ros2msg schemas), and with
rosbags' own ROS 2 Humble types plus slidetrack_msgs registered from the
.msg files in MSG_DIR; both must agree. Then each converted session channel
must be in the bag message for message (same log times, in order), with
equal values: every taxel, hand state, estimates with covariance, images,
camera info, transforms. Prints a JSON summary of the messages compared per
topic; exits 1 with the reason on the first difference.
"""

import base64
import json
import sys
from pathlib import Path

import numpy as np
from mcap.reader import make_reader
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_types_from_msg, get_typestore


def fail(why):
    raise SystemExit(why)


def stamp_ns(header):
    return header.stamp.sec * 1_000_000_000 + header.stamp.nanosec


def foxglove_ns(t):
    return t["sec"] * 1_000_000_000 + t["nsec"]


def typestore_with(msg_dir):
    store = get_typestore(Stores.ROS2_HUMBLE)
    types = {}
    for path in sorted(Path(msg_dir).glob("*.msg")):
        types.update(get_types_from_msg(path.read_text(), f"slidetrack_msgs/msg/{path.stem}"))
    store.register(types)
    return store


def read_bag(bag, store):
    """{topic: [(log_time, type, message)]}, checking both decodings agree."""
    out = {}
    with AnyReader([Path(bag)]) as reader:
        for conn, log_time, raw in reader.messages():
            if conn.msgdef.format.name != "MSG" or conn.msgtype is None:
                fail(f"{conn.topic}: schema not ros2msg")
            from_bag = reader.deserialize(raw, conn.msgtype)
            ours = store.deserialize_cdr(raw, conn.msgtype)
            if repr(from_bag) != repr(ours):
                fail(f"{conn.topic} at {log_time}: the bag's definition and ROS 2's decode differently")
            out.setdefault(conn.topic, []).append((log_time, conn.msgtype, ours))
    return out


def close(a, b):
    return np.array_equal(np.asarray(a, dtype=float), np.asarray(b, dtype=float))


def check_tactile(m, j, t):
    if stamp_ns(m.header) != t or m.sequence != j["sequence"]:
        return "header or sequence"
    if [s.name for s in m.sensors] != [s["name"] for s in j["sensors"]]:
        return "sensor names"
    for s, js in zip(m.sensors, j["sensors"]):
        for axis in "xyz":
            if getattr(s, axis).tolist() != [tx[axis] for tx in js["taxels"]]:
                return f"{s.name} {axis} taxels"
    return None


def check_hand(m, j, t):
    if stamp_ns(m.header) != t or not close(m.finger_travel, j["finger_travel"]):
        return "header or finger travel"
    if m.has_opening != (j["opening"] is not None) or (j["opening"] is not None and m.opening != j["opening"]):
        return "opening"
    g = j.get("gripper")
    if m.has_gripper != (g is not None):
        return "has_gripper"
    if g is not None and any(getattr(m.gripper, k) != v for k, v in g.items()):
        return "gripper registers"
    return None


def check_estimate(m, j, t):
    if stamp_ns(m.header) != t or m.position != j["position"] or m.velocity != j["velocity"]:
        return "header, position or velocity"
    if not close(m.covariance, np.asarray(j["covariance"]).ravel()):
        return "covariance"
    return None


def check_compressed(m, j, t):
    if stamp_ns(m.header) != foxglove_ns(j["timestamp"]) or m.header.frame_id != j["frame_id"]:
        return "header"
    if m.format != j["format"] or bytes(m.data) != base64.b64decode(j["data"]):
        return "format or data"
    return None


def check_raw_image(m, j, t):
    if stamp_ns(m.header) != foxglove_ns(j["timestamp"]) or m.header.frame_id != j["frame_id"]:
        return "header"
    if (m.width, m.height, m.encoding, m.step) != (j["width"], j["height"], j["encoding"], j["step"]):
        return "size, encoding or step"
    if bytes(m.data) != base64.b64decode(j["data"]) or m.is_bigendian != 0:
        return "data"
    return None


def check_camera_info(m, j, t):
    if stamp_ns(m.header) != foxglove_ns(j["timestamp"]) or m.header.frame_id != j["frame_id"]:
        return "header"
    if (m.width, m.height, m.distortion_model) != (j["width"], j["height"], j["distortion_model"]):
        return "size or model"
    if not all(close(getattr(m, k.lower()), j[k]) for k in ("D", "K", "R", "P")):
        return "D, K, R or P"
    return None


def check_tf(m, j, t):
    if len(m.transforms) != 1:
        return "one transform per message"
    tf = m.transforms[0]
    if stamp_ns(tf.header) != foxglove_ns(j["timestamp"]) or tf.header.frame_id != j["parent_frame_id"]:
        return "header"
    if tf.child_frame_id != j["child_frame_id"]:
        return "child frame"
    tr, rot = tf.transform.translation, tf.transform.rotation
    if [tr.x, tr.y, tr.z] != [j["translation"][k] for k in "xyz"]:
        return "translation"
    if [rot.x, rot.y, rot.z, rot.w] != [j["rotation"][k] for k in "xyzw"]:
        return "rotation"
    return None


def check_pose(m, j, t):
    if stamp_ns(m.header) != foxglove_ns(j["timestamp"]) or m.header.frame_id != j["frame_id"]:
        return "header"
    p, q = m.pose.position, m.pose.orientation
    if [p.x, p.y, p.z] != [j["pose"]["position"][k] for k in "xyz"]:
        return "position"
    if [q.x, q.y, q.z, q.w] != [j["pose"]["orientation"][k] for k in "xyzw"]:
        return "orientation"
    return None


def check_twist(m, j, t):
    if stamp_ns(m.header) != t or m.header.frame_id != j["frame_id"]:
        return "header"
    v, w = m.twist.linear, m.twist.angular
    if [v.x, v.y, v.z] != j["linear_velocity_mps"] or [w.x, w.y, w.z] != j["angular_velocity_radps"]:
        return "velocities"
    return None


def check_odometry(m, j, t):
    if stamp_ns(m.header) != t or m.header.frame_id != j["frame_id"] or m.child_frame_id != j["child_frame_id"]:
        return "header or child frame"
    p, q = m.pose.pose.position, m.pose.pose.orientation
    if [p.x, p.y, p.z] != j["position_m"] or [q.x, q.y, q.z, q.w] != [j["orientation"][k] for k in "xyzw"]:
        return "pose"
    v, w = m.twist.twist.linear, m.twist.twist.angular
    if [v.x, v.y, v.z] != j["linear_velocity_in_child_mps"] or [w.x, w.y, w.z] != j["angular_velocity_in_child_radps"]:
        return "twist"
    if not close(m.pose.covariance, j["pose_covariance"]) or not close(m.twist.covariance, j["twist_covariance"]):
        return "covariances"
    return None


def check_planar(m, j, t):
    s = j["state"]
    if stamp_ns(m.header) != t or not close(m.translation, s["translation_m"]) or m.rotation != s["rotation_rad"]:
        return "header, translation or rotation"
    if not close(m.velocity, s["velocity_m_per_s"]) or m.angular_velocity != s["angular_velocity_rad_per_s"]:
        return "velocities"
    if not close(m.covariance, j["covariance"]):
        return "covariance"
    return None


# session schema -> (ROS 2 type, bag topic or None for the session's, check)
CONVERTED = {
    "slidetrack.TactileRaw": ("slidetrack_msgs/msg/TactileRaw", None, check_tactile),
    "slidetrack.HandState": ("slidetrack_msgs/msg/HandState", None, check_hand),
    "slidetrack.SlidingEstimate": ("slidetrack_msgs/msg/SlidingEstimate", None, check_estimate),
    "foxglove.CompressedImage": ("sensor_msgs/msg/CompressedImage", None, check_compressed),
    "foxglove.RawImage": ("sensor_msgs/msg/Image", None, check_raw_image),
    "foxglove.CameraCalibration": ("sensor_msgs/msg/CameraInfo", None, check_camera_info),
    "foxglove.FrameTransform": ("tf2_msgs/msg/TFMessage", "/tf", check_tf),
    "foxglove.PoseInFrame": ("geometry_msgs/msg/PoseStamped", None, check_pose),
    "slidetrack.VelocityEstimate": ("geometry_msgs/msg/TwistStamped", None, check_twist),
    "slidetrack.Odometry": ("nav_msgs/msg/Odometry", None, check_odometry),
    "slidetrack.PlanarEstimate": ("slidetrack_msgs/msg/PlanarEstimate", None, check_planar),
}


def main():
    bag, session, msg_dir = sys.argv[1:4]
    in_bag = read_bag(bag, typestore_with(msg_dir))
    position = {topic: 0 for topic in in_bag}
    compared = {}
    with open(session, "rb") as f:
        for schema, channel, message in make_reader(f).iter_messages(log_time_order=False):
            if schema is None or schema.name not in CONVERTED:
                continue
            ros_type, bag_topic, check = CONVERTED[schema.name]
            topic = bag_topic or channel.topic
            where = f"{channel.topic} at {message.log_time}"
            entries = in_bag.get(topic, [])
            k = position.get(topic, 0)
            if k >= len(entries):
                fail(f"{where}: not in the bag (it has {len(entries)} messages on {topic})")
            log_time, msgtype, decoded = entries[k]
            position[topic] = k + 1
            if (log_time, msgtype) != (message.log_time, ros_type):
                fail(f"{where}: the bag has {msgtype} at {log_time}")
            why = check(decoded, json.loads(message.data), message.log_time)
            if why:
                fail(f"{where}: {why} differ")
            compared[channel.topic] = compared.get(channel.topic, 0) + 1
    extra = {t: len(v) - position[t] for t, v in in_bag.items() if len(v) != position[t]}
    if extra:
        fail(f"the bag has messages the session does not: {extra}")
    json.dump(compared, sys.stdout)


if __name__ == "__main__":
    main()
